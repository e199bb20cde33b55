"""bench_fault_soak's arguments (anyscale_testbed.soak_run.parse_args): what is required and
what is checked, each a one-line error and exit 2."""
import pytest

from anyscale_testbed.soak_run import parse_args


def test_the_cfs_period_is_the_kernels_unless_asked_for():
    assert parse_args(["--minutes", "1", "--seed", "1"]).cfs_period_ms == 100
    asked = parse_args(["--minutes", "1", "--seed", "1", "--cfs-period-ms", "10"])
    assert asked.cfs_period_ms == 10


@pytest.mark.parametrize("argv,message", [
    ([], "--minutes and --seed are required"),
    (["--minutes", "0", "--seed", "1"], "--minutes: expected a number of minutes in (0, 1440]"),
    (["--minutes", "1", "--seed", "1", "--cfs-period-ms", "2000"],
     "--cfs-period-ms: expected 1 to 1000 ms (the kernel's limits), got 2000"),
    (["--minutes", "1", "--seed", "1", "--robot-cpu", "-1"], "--robot-cpu: expected cores > 0"),
])
def test_bad_arguments_are_one_line_and_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as ended:
        parse_args(argv)
    assert ended.value.code == 2
    assert message in capsys.readouterr().err
