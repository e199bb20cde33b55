"""scripts/run_testbed.py's arguments (anyscale_testbed.demo_run.parse_args): the WiFi seed."""
import pytest

from anyscale_testbed.demo_run import parse_args


def test_seed_defaults_to_the_deterministic_model_and_passes_through():
    assert parse_args([], "out").seed == 0
    assert parse_args(["--seed", "3"], "out").seed == 3


@pytest.mark.parametrize("argv,message", [
    (["--seed", "-1"], "--seed: expected an integer >= 0"),
    (["--seed", "2", "--link", "schedule"], "--seed varies the coverage model"),
    (["--seed", "x"], "--seed: invalid int value"),
])
def test_a_bad_seed_is_one_line_and_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as ended:
        parse_args(argv, "out")
    assert ended.value.code == 2
    assert message in capsys.readouterr().err
