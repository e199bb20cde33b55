"""The evaluation command end to end, shortened for CI (root: network namespaces, tc, cgroups;
conftest.py skips without them): scripts/run_evaluation.py on the small loop with one
interleaved pair (the baseline, then the seeded AnyScale test), each ended after DURATION_S,
writes the table (text, Markdown, CSV) and Fig. 5 and Fig. 6; run again, it runs nothing and
writes them anew. About 2 x (DURATION_S + ~25 s of set-up and teardown): under 3 minutes. The
full evaluation is a bench (its README section), too long for CI."""
import csv
import glob
import os
import subprocess
import sys

import pytest

from anyscale_testbed.calibration_file import quota_cores

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", ".."))
DURATION_S = 30.0
RUNS = "pair1-baseline,pair1-paper"
OUTPUTS = ("evaluation.txt", "evaluation.md", "evaluation.csv", "fig5_paths.png",
           "fig6_time_and_omega.png")


def evaluate(out, timeout_s):
    # At the calibration file's quota: --robot-cpu auto's calibration runs (2 minutes each)
    # are tested without the test bed (test_evaluation_run.py).
    robot_cpu, _ = quota_cores(None, None)
    return subprocess.run(
        [sys.executable, os.path.join(ROOT, "scripts", "run_evaluation.py"), "--world",
         "small_loop", "--seeds", "1", "--runs", RUNS, "--duration",
         str(DURATION_S), "--robot-cpu", str(robot_cpu), "--out", str(out)],
        capture_output=True, text=True, timeout=timeout_s)


@pytest.fixture(scope="module")
def evaluation(tmp_path_factory):
    out = tmp_path_factory.mktemp("evaluation")
    done = evaluate(out, 2 * (DURATION_S + 120))
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    print(done.stdout)      # the command's own account, shown with -s or on failure
    return out, done.stdout


def test_each_run_is_recorded_with_its_progress_line(evaluation):
    out, printed = evaluation
    for k, key in enumerate(RUNS.split(","), 1):
        assert glob.glob(str(out / key / "*" / "record.json")), key
        assert f"[{k}/2] {key}: done in" in printed
    # The seeded test ran on the coverage link with its seed, the baseline with the link down.
    assert glob.glob(str(out / "pair1-paper" / "small_loop-coverage-seed1-*" / "record.json"))
    with open(out / "pair1-paper" / "console.log") as f:
        assert "link coverage seed 1" in f.read()
    with open(out / "pair1-baseline" / "console.log") as f:
        assert "link schedule" in f.read()


def test_it_writes_the_table_and_the_figures(evaluation):
    out, printed = evaluation
    for name in OUTPUTS:
        assert os.path.getsize(out / name) > 0, name
    with open(out / "evaluation.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["kind"] for r in rows] == ["baseline", "paper"]
    assert "paper vs here:" in printed
    with open(out / "evaluation.md") as f:
        assert "## The paper beside this test bed" in f.read()


def test_a_second_call_resumes_and_runs_nothing(evaluation):
    out, _ = evaluation
    for name in OUTPUTS:
        os.remove(out / name)
    done = evaluate(out, 120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "[1/2] pair1-baseline: recorded already, not run again" in done.stdout
    assert "[2/2] pair1-paper: recorded already, not run again" in done.stdout
    for name in OUTPUTS:            # written anew from the records
        assert os.path.getsize(out / name) > 0, name
