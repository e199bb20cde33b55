"""`anyscale simulate`: the study's command, registered with anyscale_core's CLI through this
package's package.xml export (anyscale_core.cli_plugins)."""
import pytest

from anyscale_core.cli import main
from anyscale_core.cli_plugins import registered_modules


def test_the_study_registers_simulate_through_its_package_xml():
    assert ("anyscale_study", "anyscale_study.cli_simulate") in registered_modules()


def test_simulate_has_help_through_the_anyscale_command(capsys):
    with pytest.raises(SystemExit) as done:
        main(["simulate", "--help"])
    assert done.value.code == 0
    assert "usage: anyscale simulate" in capsys.readouterr().out


def test_the_anyscale_command_lists_simulate_last(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--help"])
    assert done.value.code == 0
    listed = [line.split()[0] for line in capsys.readouterr().out.splitlines()
              if line.startswith("    ") and not line.startswith("     ")]
    assert listed == ["check", "plan", "top", "model", "profile", "thresholds", "simulate"]
