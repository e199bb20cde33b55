"""tests/bench/bench_tolerances.py's command line for each run (imported from its file; the
bench itself needs root and the test bed): --normalise-cpu reaches run_testbed.py."""
import importlib.util
import os

import pytest

BENCH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "tests",
                     "bench", "bench_tolerances.py")


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_tolerances", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_normalise_cpu_reaches_run_testbed_only_when_asked_for(bench):
    plain = bench.parse_args([])
    assert plain.normalise_cpu is False
    argv = bench.run_argv(plain, 2, 13, "out/run03")
    assert "--normalise-cpu" not in argv
    assert argv[1] == bench.RUN_TESTBED and argv[argv.index("--seed") + 1] == "13"
    assert argv[argv.index("--start-goal") + 1] == "2"
    normalised = bench.parse_args(["--normalise-cpu", "--runs", "2"])
    argv = bench.run_argv(normalised, 0, 11, "out/run01")
    assert argv.count("--normalise-cpu") == 1 and argv[argv.index("--out") + 1] == "out/run01"
