"""The evaluation runner without a test bed: its plan, --runs and --seeds, resuming from the
runs recorded, and the table and figures it writes (each run faked by a synthetic record)."""
import os

import numpy as np
import pytest

from anyscale_testbed import evaluation_run
from anyscale_testbed.evaluation_figures import AMCL_ON_LAPTOP, BOTH_ON_ROBOT
from anyscale_nav_demo.results import configuration_runs
from anyscale_testbed.evaluation_run import (amcl_bandwidth_mbps, evaluation_plan, parse_args,
                                             parse_seeds, select_runs)
from test_evaluation_table import record


def test_the_plan_is_baselines_seeded_tests_per_allocator_and_best_case():
    plan = evaluation_plan([1, 2, 3, 4])
    assert [r.key for r in plan] == (
        ["baseline", "baseline-2"] + [f"{a}-seed{s}" for a in ("paper", "paper_local", "optimal")
                                      for s in (1, 2, 3, 4)] + ["best_case"])
    assert plan[0].argv == plan[1].argv == ["--link", "schedule", "--schedule", "[[0, 0]]"]
    assert plan[1].title == "baseline (no migration), run 2"
    assert plan[-1].argv == ["--link", "schedule", "--schedule", "[[0, 27]]"]
    assert plan[7].argv == ["--link", "coverage", "--seed", "2", "--allocator", "paper_local"]
    assert plan[2].title == "AnyScale, seed 1" and plan[6].title == "AnyScale paper_local, seed 1"
    assert [r.key for r in evaluation_plan([1], baseline_runs=3)[:3]] == [
        "baseline", "baseline-2", "baseline-3"]


def test_runs_are_selected_by_key_or_kind_and_unknown_names_are_refused():
    plan = evaluation_plan([1, 2])
    assert [r.key for r in select_runs(plan, "baseline,paper")] == [
        "baseline", "baseline-2", "paper-seed1", "paper-seed2"]
    assert [r.key for r in select_runs(plan, "optimal-seed2, best_case")] == [
        "optimal-seed2", "best_case"]
    assert select_runs(plan, None) == plan
    with pytest.raises(ValueError, match="--runs: unknown paper-seed3"):
        select_runs(plan, "paper-seed3")
    assert parse_seeds("1,2,3,4") == [1, 2, 3, 4]
    for bad in ("0,1", "1,1", "a", ""):
        with pytest.raises(ValueError, match="--seeds"):
            parse_seeds(bad)


def test_bad_arguments_are_one_line_and_exit_2(capsys):
    for argv in (["--runs", "nope"], ["--seeds", "x"], ["--duration", "-5"],
                 ["--baseline-runs", "0"]):
        with pytest.raises(SystemExit) as ended:
            parse_args(argv, "out")
        assert ended.value.code == 2
        assert "error: --" in capsys.readouterr().err.strip().splitlines()[-1]


def test_amcl_moves_its_scans_and_its_pose_over_the_link():
    from anyscale_testbed.demo_run import nav_demo_path
    assert amcl_bandwidth_mbps(nav_demo_path("config", "testbed.yaml")) == pytest.approx(0.22)


def test_path_segments_keep_the_line_whole():
    xy = np.array([[0, 0], [1, 0], [2, 0], [3, 0], [4, 0]], dtype=float)
    runs = configuration_runs(xy, ["a", "a", "b", "b", "a"])
    assert [c for c, _ in runs] == ["a", "b", "a"]
    assert [p[:, 0].tolist() for _, p in runs] == [[0, 1], [1, 2, 3], [3, 4]]


class FakeRuns:
    """Stands in for run_testbed.py: writes a synthetic record where a run would."""

    def __init__(self):
        self.argvs = []

    def __call__(self, argv, out_dir):
        self.argvs.append(argv)
        slow = "[[0, 0]]" in argv
        rec = record(done_t=210.0 if slow else 150.0, mappings=[] if slow else None)
        # Back and forth along the small loop's south corridor (y = 3.4 m), inside the map.
        rec.truth = [(t, 3.4 + abs((x % 12.0) - 6.0), 3.4) for t, x, _ in rec.truth]
        run_dir = os.path.join(out_dir, "small_loop-fake")
        os.makedirs(run_dir)
        rec.save(os.path.join(run_dir, "record.json"))
        return 0


def test_the_evaluation_runs_what_is_not_recorded_yet_and_writes_table_and_figures(
        tmp_path, monkeypatch, capsys):
    fake = FakeRuns()
    monkeypatch.setattr(evaluation_run, "run_logged", fake)
    monkeypatch.setattr(evaluation_run, "start_on_the_testbed", lambda program: None)
    out = str(tmp_path / "eval")
    argv = ["--world", "small_loop", "--seeds", "1", "--baseline-runs", "1",
            "--runs", "baseline,paper", "--duration", "50", "--out", out]
    # A path that cannot run: were the fake not in place, nothing would start a test bed.
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", argv) == 0
    assert [a[a.index("--link"):] for a in fake.argvs] == [
        ["--link", "schedule", "--schedule", "[[0, 0]]"],
        ["--link", "coverage", "--seed", "1", "--allocator", "paper"]]
    assert all(a[a.index("--duration") + 1] == "50.0" for a in fake.argvs)
    printed = capsys.readouterr().out
    assert "[1/2] baseline: baseline (no migration)" in printed
    assert "[2/2] paper-seed1: done in" in printed and "time to complete 140 s" in printed
    for name in ("evaluation.txt", "evaluation.md", "evaluation.csv", "fig5_paths.png",
                 "fig6_time_and_omega.png"):
        assert os.path.getsize(os.path.join(out, name)) > 0, name
    with open(os.path.join(out, "evaluation.md")) as f:
        md = f.read()
    assert "| AnyScale, seed 1 | 0 | 140 s | 30.0 % |" in md
    assert os.path.exists(os.path.join(out, "paper-seed1", "exit_code"))
    # Again, with the best case added: the two recorded runs are not run again.
    fake.argvs.clear()
    argv[argv.index("baseline,paper")] = "baseline,paper,best_case"
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", argv) == 0
    assert [a[a.index("--link"):] for a in fake.argvs] == [
        ["--link", "schedule", "--schedule", "[[0, 27]]"]]
    printed = capsys.readouterr().out
    assert "[1/3] baseline: recorded already, not run again" in printed
    assert "best case (network everywhere)" in printed


def test_fig5_colours_the_paths_by_configuration(tmp_path, monkeypatch):
    import matplotlib.image
    fake = FakeRuns()
    monkeypatch.setattr(evaluation_run, "run_logged", fake)
    monkeypatch.setattr(evaluation_run, "start_on_the_testbed", lambda program: None)
    out = str(tmp_path / "eval")
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py",
                               ["--world", "small_loop", "--seeds", "1", "--runs", "paper",
                                "--out", out]) == 0
    image = matplotlib.image.imread(os.path.join(out, "fig5_paths.png"))[:, :, :3]
    def has(colour):
        rgb = np.array([int(colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])
        return bool(np.any(np.all(np.abs(image - rgb) < 0.02, axis=2)))
    from anyscale_testbed.evaluation_figures import CONFIGURATION_COLOURS
    assert has(CONFIGURATION_COLOURS[AMCL_ON_LAPTOP]) and has(CONFIGURATION_COLOURS[BOTH_ON_ROBOT])
