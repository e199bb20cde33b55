"""The evaluation runner without a test bed: its plan in either order, --runs and --seeds,
resuming from the runs recorded (also under the other order's keys), and the table and figures
it writes (each run faked by a synthetic record)."""
import os
import shutil

import numpy as np
import pytest

from anyscale_testbed import evaluation_figures, evaluation_run, quota_for_the_day
from anyscale_testbed.evaluation_figures import AMCL_ON_LAPTOP, BOTH_ON_ROBOT
from anyscale_nav_demo.results import configuration_runs
from anyscale_testbed.evaluation_run import (amcl_bandwidth_mbps, evaluation_plan, parse_args,
                                             parse_seeds, run_argv, run_of_key, runs_to_collect,
                                             select_runs)
from test_evaluation_table import on, record


def test_the_grouped_plan_is_baselines_seeded_tests_per_allocator_and_best_case():
    plan = evaluation_plan([1, 2, 3, 4], "grouped")
    assert [r.key for r in plan] == (
        ["baseline", "baseline-2"] + [f"{a}-seed{s}" for a in ("paper", "paper_local", "optimal")
                                      for s in (1, 2, 3, 4)] + ["best_case"])
    assert plan[0].argv == plan[1].argv == ["--link", "schedule", "--schedule", "[[0, 0]]"]
    assert plan[1].title == "baseline (no migration), run 2"
    assert plan[-1].argv == ["--link", "schedule", "--schedule", "[[0, 27]]"]
    assert plan[7].argv == ["--link", "coverage", "--seed", "2", "--allocator", "paper_local"]
    assert plan[2].title == "AnyScale, seed 1" and plan[6].title == "AnyScale paper_local, seed 1"
    assert [r.key for r in evaluation_plan([1], "grouped", baseline_runs=3)[:3]] == [
        "baseline", "baseline-2", "baseline-3"]
    assert all(r.pair == 0 for r in plan)


def test_the_paired_plan_runs_each_seeds_baseline_just_before_its_test():
    plan = evaluation_plan([1, 2, 3, 4])
    assert [r.key for r in plan] == (
        [k for s in (1, 2, 3, 4) for k in (f"pair{s}-baseline", f"pair{s}-paper")]
        + [f"{a}-seed{s}" for a in ("paper_local", "optimal") for s in (1, 2, 3, 4)]
        + ["best_case"])
    baseline, test = plan[2], plan[3]
    assert (baseline.kind, baseline.pair, test.kind, test.pair, test.seed) == (
        "baseline", 2, "paper", 2, 2)
    assert baseline.argv == ["--link", "schedule", "--schedule", "[[0, 0]]"]
    assert test.argv == ["--link", "coverage", "--seed", "2", "--allocator", "paper"]
    assert (baseline.title, test.title) == ("pair 2: baseline (no migration)",
                                            "pair 2: AnyScale, seed 2")
    assert plan[8].pair == 0 and plan[8].title == "AnyScale paper_local, seed 1"
    # Any seeds: the pairs follow them; --baseline-runs does not count here.
    assert [r.key for r in evaluation_plan([3, 1], "paired", baseline_runs=5)[:4]] == [
        "pair3-baseline", "pair3-paper", "pair1-baseline", "pair1-paper"]
    with pytest.raises(ValueError, match="--order"):
        evaluation_plan([1], "interleaved")


def test_keys_of_either_order_name_their_run_and_nothing_else_does():
    for key in ("baseline", "baseline-6", "paper-seed2", "paper_local-seed3", "optimal-seed4",
                "best_case", "pair1-baseline", "pair12-paper"):
        assert run_of_key(key).key == key
    assert run_of_key("baseline-6").title == "baseline (no migration), run 6"
    assert run_of_key("baseline-6").pair == 0 and run_of_key("pair12-paper").pair == 12
    for other in ("baseline-1", "baseline-0", "paper-seed0", "paper-seed01", "pair0-paper",
                  "pair1-optimal", "bestcase", "fig5", "baseline-2x", ""):
        assert run_of_key(other) is None, other


def test_results_recorded_in_the_grouped_order_still_load_beside_the_paired_plan():
    plan = evaluation_plan([1, 2])
    recorded = ["paper-seed2", "baseline-2", "pair1-paper", "best_case", "baseline",
                "paper-seed1", "notes", "baseline-10"]
    loaded = runs_to_collect(plan, recorded)
    assert loaded[:len(plan)] == plan
    # The grouped order's runs, outside any pair, in their order; stray names left out.
    assert [r.key for r in loaded[len(plan):]] == [
        "baseline", "baseline-2", "baseline-10", "paper-seed1", "paper-seed2"]
    assert all(r.pair == 0 for r in loaded[len(plan):])
    # And the other way round: pairs recorded beside a grouped plan.
    grouped = evaluation_plan([1], "grouped", baseline_runs=1)
    assert [r.key for r in runs_to_collect(grouped, ["pair2-paper", "pair2-baseline"])][-2:] \
        == ["pair2-baseline", "pair2-paper"]
    assert runs_to_collect(plan, []) == plan


def test_runs_are_selected_by_key_or_kind_and_unknown_names_are_refused():
    assert [r.key for r in select_runs(evaluation_plan([1, 2]), "baseline,paper")] == [
        "pair1-baseline", "pair1-paper", "pair2-baseline", "pair2-paper"]
    plan = evaluation_plan([1, 2], "grouped")
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
                 ["--order", "grouped", "--baseline-runs", "0"], ["--baseline-runs", "2"],
                 ["--runs", "baseline-2"]):
        with pytest.raises(SystemExit) as ended:
            parse_args(argv, "out")
        assert ended.value.code == 2
        assert "error: --" in capsys.readouterr().err.strip().splitlines()[-1]


def test_normalise_cpu_is_passed_to_every_run_only_when_asked_for():
    plan = evaluation_plan([1])
    plain = parse_args([], "out")
    normalised = parse_args(["--normalise-cpu"], "out")
    assert plain.normalise_cpu is False and normalised.normalise_cpu is True
    for run in plan:
        argv = run_argv(run, plain, "run_testbed.py", "out/x")
        assert "--normalise-cpu" not in argv and argv[-len(run.argv):] == run.argv
        argv = run_argv(run, normalised, "run_testbed.py", "out/x")
        assert argv.count("--normalise-cpu") == 1 and argv[-len(run.argv):] == run.argv
        assert argv[1:4] == ["run_testbed.py", "--world", "office_floor"]


def test_a_given_quota_is_passed_to_every_run_and_a_bad_one_refused(capsys):
    args = parse_args(["--robot-cpu", "0.3"], "out")
    for run in evaluation_plan([1]):
        argv = run_argv(run, args, "run_testbed.py", "out/x", args.robot_cpu)
        assert argv[argv.index("--robot-cpu") + 1] == "0.3"
    assert parse_args([], "out").robot_cpu is None       # auto: calibrated for the day
    for bad in ("fast", "0", "-1"):
        with pytest.raises(SystemExit):
            parse_args(["--robot-cpu", bad], "out")
        assert "--robot-cpu" in capsys.readouterr().err


def test_amcl_moves_its_scans_and_its_pose_over_the_link():
    from anyscale_testbed.calibration_file import nav_demo_path
    assert amcl_bandwidth_mbps(nav_demo_path("config", "testbed.yaml")) == pytest.approx(0.22)


def test_path_segments_keep_the_line_whole():
    xy = np.array([[0, 0], [1, 0], [2, 0], [3, 0], [4, 0]], dtype=float)
    runs = configuration_runs(xy, ["a", "a", "b", "b", "a"])
    assert [c for c, _ in runs] == ["a", "b", "a"]
    assert [p[:, 0].tolist() for _, p in runs] == [[0, 1], [1, 2, 3], [3, 4]]


class FakeRuns:
    """Stands in for run_testbed.py: writes a synthetic record where a run would."""

    def __init__(self, baseline_done_t=210.0):
        self.argvs = []
        self.baseline_done_t = baseline_done_t

    def __call__(self, argv, out_dir):
        self.argvs.append(argv)
        slow = "[[0, 0]]" in argv
        rec = record(done_t=self.baseline_done_t if slow else 150.0,
                     mappings=[] if slow else None)
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
    argv = ["--world", "small_loop", "--seeds", "1", "--order", "grouped", "--baseline-runs", "1",
            "--runs", "baseline,paper", "--duration", "50", "--robot-cpu", "0.34", "--out", out]
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


def test_the_paired_evaluation_runs_pairs_and_keeps_the_runs_recorded_in_the_grouped_order(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(evaluation_run, "start_on_the_testbed", lambda program: None)
    out = str(tmp_path / "eval")
    grouped = ["--world", "small_loop", "--seeds", "1", "--order", "grouped",
               "--baseline-runs", "1", "--runs", "baseline,paper", "--robot-cpu", "0.34",
               "--out", out]
    # A baseline of another day: 300 s to complete.
    monkeypatch.setattr(evaluation_run, "run_logged", FakeRuns(baseline_done_t=310.0))
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", grouped) == 0
    fake = FakeRuns()           # today's: 200 s
    monkeypatch.setattr(evaluation_run, "run_logged", fake)
    paired = ["--world", "small_loop", "--seeds", "1,2", "--runs", "baseline,paper",
              "--robot-cpu", "0.34", "--out", out]
    capsys.readouterr()
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", paired) == 0
    assert [a[a.index("--link") + 1] for a in fake.argvs] == [
        "schedule", "coverage", "schedule", "coverage"]
    assert [a[a.index("--out") + 1] for a in fake.argvs] == [
        os.path.join(out, k) for k in ("pair1-baseline", "pair1-paper", "pair2-baseline",
                                       "pair2-paper")]
    printed = capsys.readouterr().out
    assert "[1/4] pair1-baseline: pair 1: baseline (no migration)" in printed
    with open(os.path.join(out, "evaluation.md")) as f:
        md = f.read()
    # The day-old runs are in the table; each paired test is measured against its own
    # baseline (200 s: 30 %), the mean of all three against 233 s.
    assert "| baseline (no migration) | 0 | 300 s |" in md
    assert "| AnyScale, seed 1 | 0 | 140 s | 40.0 % | - |" in md
    assert "| pair 1: AnyScale, seed 1 | 0 | 140 s | 40.0 % | 30.0 % |" in md
    assert "paired gain of the AnyScale tests (each against the baseline run just before it): " \
           "30.0 % (sd 0.0 %, 30.0 to 30.0 %, 2 pairs)" in md
    # Run again: everything is recorded, nothing runs.
    fake.argvs.clear()
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", paired) == 0
    assert fake.argvs == []
    assert "[4/4] pair2-paper: recorded already, not run again" in capsys.readouterr().out


def test_fig5_colours_the_paths_by_configuration(tmp_path, monkeypatch):
    import matplotlib.image
    fake = FakeRuns()
    monkeypatch.setattr(evaluation_run, "run_logged", fake)
    monkeypatch.setattr(evaluation_run, "start_on_the_testbed", lambda program: None)
    out = str(tmp_path / "eval")
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py",
                               ["--world", "small_loop", "--seeds", "1", "--runs", "paper",
                                "--robot-cpu", "0.34", "--out", out]) == 0
    image = matplotlib.image.imread(os.path.join(out, "fig5_paths.png"))[:, :, :3]

    def has(colour):
        rgb = np.array([int(colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])
        return bool(np.any(np.all(np.abs(image - rgb) < 0.02, axis=2)))
    from anyscale_testbed.evaluation_figures import CONFIGURATION_COLOURS
    assert has(CONFIGURATION_COLOURS[AMCL_ON_LAPTOP]) and has(CONFIGURATION_COLOURS[BOTH_ON_ROBOT])


class MachineOfTheDay(FakeRuns):
    """FakeRuns on a machine faster than the calibrated one: with every node home AMCL runs at
    2 Hz at 0.27 cores, 2.82 Hz at the calibration file's 0.34 (a calibration run's record
    holds only that rate)."""

    def __call__(self, argv, out_dir):
        if not os.path.basename(os.path.dirname(out_dir)).endswith("calibration"):
            return super().__call__(argv, out_dir)
        self.argvs.append(argv)
        quota = float(argv[argv.index("--robot-cpu") + 1])
        rec = record(done_t=None, mappings=[(0.0, on(), 0.0, 0.0)],
                     amcl_hz=2.0 * (quota - 0.10) / 0.17)
        os.makedirs(os.path.join(out_dir, "small_loop-fake"))
        rec.save(os.path.join(out_dir, "small_loop-fake", "record.json"))
        return 0


def test_robot_cpu_auto_calibrates_each_pair_to_the_premise_and_keeps_it(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(evaluation_run, "start_on_the_testbed", lambda program: None)
    monkeypatch.setattr(quota_for_the_day, "quota_cores", lambda robot, laptop: (0.34, 0.9))
    fake = MachineOfTheDay()
    monkeypatch.setattr(evaluation_run, "run_logged", fake)
    monkeypatch.setattr(quota_for_the_day, "run_logged", fake)
    out = str(tmp_path / "eval")
    argv = ["--world", "small_loop", "--seeds", "1,2", "--runs", "baseline,paper", "--out", out]
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", argv) == 0
    outs = [a[a.index("--out") + 1] for a in fake.argvs]
    quotas = [a[a.index("--robot-cpu") + 1] for a in fake.argvs]
    # Pair 1: 0.34 cores read 2.82 Hz, the proportional step gave 0.288 (2.21 Hz: kept);
    # pair 2 starts there and keeps it after one run.
    assert [os.path.relpath(o, out) for o in outs] == [
        "pair1-calibration/run1", "pair1-calibration/run2", "pair1-baseline", "pair1-paper",
        "pair2-calibration/run1", "pair2-baseline", "pair2-paper"]
    assert quotas == ["0.34", "0.288", "0.288", "0.288", "0.288", "0.288", "0.288"]
    # Calibration runs are short and with every node home.
    assert fake.argvs[0][fake.argvs[0].index("--link"):] == ["--link", "schedule", "--schedule",
                                                             "[[0, 0]]"]
    assert float(fake.argvs[0][fake.argvs[0].index("--duration") + 1]) < 200
    printed = capsys.readouterr().out
    assert "pair1-calibration: calibration: robot 0.34 cores, AMCL 2.82 Hz at home" in printed
    assert "[1/4] pair1-baseline: pair 1: baseline (no migration), robot 0.288 cores" in printed
    with open(os.path.join(out, "evaluation.md")) as f:
        md = f.read()
    assert "| pair1-calibration | 0.288 | 0.34 cores: 2.82 Hz, 0.288 cores: 2.21 Hz | - |" in md
    # An interrupted evaluation resumes at the quota its pair was calibrated to.
    for key in ("pair2-baseline", "pair2-paper"):
        shutil.rmtree(os.path.join(out, key))
    fake.argvs.clear()
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", argv) == 0
    assert [a[a.index("--robot-cpu") + 1] for a in fake.argvs] == ["0.288", "0.288"]
    assert "pair2-calibration: robot 0.288 cores, calibrated already" in capsys.readouterr().out
    # A calibration not made yet when the evaluation resumes starts from the newest one made.
    shutil.rmtree(os.path.join(out, "pair2-calibration"))
    for key in ("pair2-baseline", "pair2-paper"):
        shutil.rmtree(os.path.join(out, key))
    fake.argvs.clear()
    assert evaluation_run.main("unused", "/nonexistent/run_testbed.py", argv) == 0
    assert [a[a.index("--robot-cpu") + 1] for a in fake.argvs][0] == "0.288"


def test_laps_and_the_link_forecast_options_reach_the_runs(tmp_path, capsys):
    from anyscale_core.link_map import LinkMap
    plan = evaluation_plan([1])
    plain = parse_args([], "out")
    for run in plan:
        argv = run_argv(run, plain, "run_testbed.py", "out/x")
        assert not {"--loops", "--no-forecast", "--link-map"} & set(argv)
    saved = tmp_path / "earlier" / "pair1-paper" / "office_floor-coverage-seed1-x"
    saved.mkdir(parents=True)
    m = LinkMap()
    m.add("laptop", 1.8e9, 1.0, 1.0, 20.0, False)
    m.save(str(saved / "link_map.yaml"))
    for link_map, expected in ((str(saved / "link_map.yaml"), str(saved / "link_map.yaml")),
                               (str(tmp_path / "earlier"), str(saved / "link_map.yaml"))):
        args = parse_args(["--laps", "2", "--no-forecast", "--link-map", link_map], "out")
        for run in plan:
            argv = run_argv(run, args, "run_testbed.py", "out/x")
            assert argv[argv.index("--loops") + 1] == "2"
            assert argv[-len(run.argv):] == run.argv
            test = run.kind in ("paper", "paper_local", "optimal")
            assert ("--no-forecast" in argv) == test, run.key
            if run.key == "pair1-paper" or test and not os.path.isdir(link_map):
                assert argv[argv.index("--link-map") + 1] == expected
            else:           # no test, or a test whose namesake saved no map there
                assert "--link-map" not in argv
    # A directory without the namesake's map: that test starts from an empty map, said so.
    args = parse_args(["--link-map", str(tmp_path / "earlier")], "out")
    other = evaluation_run.seeded_test("paper", 2)
    assert "--link-map" not in run_argv(other, args, "run_testbed.py", "out/x")
    assert "paper-seed2: no link map in" in capsys.readouterr().out
    for bad, says in ((["--laps", "0"], "--laps: expected 1 to 20"),
                      (["--link-map", str(tmp_path / "nope.yaml")], "nope.yaml: no such file")):
        with pytest.raises(SystemExit):
            parse_args(bad, "out")
        assert says in capsys.readouterr().err


def test_returns_are_marked_where_the_robot_was(tmp_path):
    from anyscale_testbed.testbed_record import (LINK_AHEAD_RETURN, LINK_LOSS_RETURN,
                                                 EventRecord)
    rec = record()
    rec.events = [EventRecord(40.0, "migrate_back", "amcl", "laptop", "robot",
                              "link to laptop down", 0.3, True, 40.0),
                  EventRecord(70.0, "migrate_back", "amcl", "laptop", "robot",
                              "link ahead: 0.0 Mbit/s in 2.8 s", 0.3, True, 70.0),
                  EventRecord(50.0, "migrate", "amcl", "robot", "laptop", "x", 0.3, True, 50.0),
                  EventRecord(200.0, "migrate_back", "amcl", "laptop", "robot",
                              "link to laptop down", 0.3, True, 200.0)]   # after the mission
    marks = evaluation_figures.returns_along_path(rec)
    assert [k for _, _, k in marks] == [LINK_LOSS_RETURN, LINK_AHEAD_RETURN]
    x_at = dict((t, x) for t, x, _ in rec.truth)
    assert marks[0][:2] == (pytest.approx(x_at[40.0]), 0.0)
    from anyscale_testbed.evaluation_plots import draw_fig5
    png = str(tmp_path / "fig5.png")
    xy = np.array([[0.0, 0.0], [1.0, 0.0]])
    draw_fig5(png, np.zeros((10, 10), bool), np.zeros((10, 10), bool), 0.5, (0.0, 0.0),
              [("t", xy, [BOTH_ON_ROBOT] * 2, [(0.5, 0.0, LINK_LOSS_RETURN)])])
    assert os.path.getsize(png) > 0
