"""The anyscale CLI as a user runs it: check and plan output, --json, and one-line errors with
exit status 2 (never a traceback)."""
import json
import os
import subprocess
import sys

import pytest

from anyscale_core.cli import main
from anyscale_core.cli_plugins import registered_modules

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "scripts", "anyscale")


def test_check_testbed(testbed_path, capsys):
    assert main(["check", testbed_path]) == 0
    out = capsys.readouterr().out
    assert "migratable nodes (2):" in out
    assert "amcl" in out and "ar_recognition" in out
    assert "2048 before pruning, 4 after pinning, 4 after memory" in out


def test_plan_json(testbed_path, tmp_path, capsys):
    state = tmp_path / "state.yaml"
    state.write_text("bandwidth_mbps: 3\n")
    assert main(["plan", testbed_path, "--state", str(state), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert set(result) == {"mapping", "perf", "feasible", "solver"}
    assert result["mapping"]["amcl"] == "laptop"
    assert result["mapping"]["ar_recognition"] == "robot"
    assert result["feasible"] is True and result["solver"] == "paper"


@pytest.mark.parametrize("solver", ["paper", "optimal"])
def test_plan_link_down_keeps_everything_home(testbed_path, tmp_path, capsys, solver):
    state = tmp_path / "state.yaml"
    state.write_text("link_up: {laptop: false}\n")
    assert main(["plan", testbed_path, "--state", str(state), "--solver", solver]) == 0
    out = capsys.readouterr().out
    assert "feasible: yes" in out and "-> laptop" not in out


def test_bad_inputs_exit_2_with_one_line(testbed_path, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("scales: [\n")
    assert main(["check", str(bad)]) == 2
    assert main(["plan", testbed_path, "--solver", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith(f"anyscale check: error: {bad}: invalid YAML")
    assert err[1] == "anyscale plan: error: --solver: unknown allocator 'nope' (known: " \
                     "optimal, paper, paper_local)"


def test_script_reports_errors_without_traceback(tmp_path):
    bad = tmp_path / "model.yaml"
    bad.write_text("scales: []\nnetwork: {max_bandwidth_mbps: 1}\nnodes: []\nconnections: []\n")
    run = subprocess.run([sys.executable, SCRIPT, "check", str(bad)], capture_output=True,
                         text=True, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert run.returncode == 2
    assert "Traceback" not in run.stderr
    assert f"{bad}: scales: expected at least one scale" in run.stderr


def test_a_reader_that_goes_away_ends_the_command_quietly(testbed_path):
    """`anyscale check MODEL | head -1`: the pipe closes before the output is written."""
    proc = subprocess.Popen([sys.executable, SCRIPT, "check", testbed_path],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=30) in (0, 141)
    assert "Traceback" not in err and "BrokenPipeError" not in err, err


@pytest.mark.parametrize("command", ["check", "plan", "profile", "thresholds", "top",
                                     "model draft"])
def test_every_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as done:
        main(command.split() + ["--help"], plugins=[])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "usage: anyscale " + command in out
    assert "example" in out


@pytest.mark.parametrize("argv,message", [
    (["profile"], "anyscale profile: error: the following arguments are required: MODEL "
                  "(see anyscale profile --help)"),
    (["profile", "m.yaml", "--window", "-3"], "anyscale profile: error: argument --window: "
                                              "expected a number in (0, 86400], got -3"),
    (["thresholds", "m.yaml", "--connection", "a:b:/t"],
     "anyscale thresholds: error: one of the arguments --probe --probe-script is required"),
    (["thresholds", "m.yaml", "--connection", "a:b:/t", "--probe", "/p", "--probe-script",
      "x"], "argument --probe-script: not allowed with argument --probe"),
    (["thresholds", "m.yaml", "--connection", "a:b:/t", "--rates", "5,x", "--probe", "/p"],
     "argument --rates: expected numbers separated by commas, got '5,x'"),
])
def test_usage_errors_are_one_line_and_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as done:
        main(argv)
    assert done.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_profile_and_thresholds_refuse_bad_files_and_options(testbed_path, tmp_path, capsys):
    missing = str(tmp_path / "none.yaml")
    assert main(["profile", missing]) == 2
    assert main(["thresholds", testbed_path, "--connection", "laser:amcl:/scan",
                 "--probe", "/amcl_error"]) == 2
    assert main(["thresholds", testbed_path, "--connection", "laser:amcl:/scan",
                 "--probe", "/e", "--condition", "m.data < 1", "--quota", "1.5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"anyscale profile: error: {missing}: no such file",
                   "anyscale thresholds: error: --probe: needs --condition EXPR (true when "
                   "correct)",
                   "anyscale thresholds: error: --quota: expected a share in (0, 1], got 1.5"]


def test_simulate_without_the_study_says_what_to_install(capsys):
    assert main(["simulate", "--runs", "1"], plugins=[]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["anyscale simulate: needs the package anyscale_study (the paper's Fig. 7 "
                   "study); build or install it beside anyscale_core"]


def test_a_broken_plugin_is_named_and_the_other_commands_still_work(testbed_path, capsys):
    assert main(["check", testbed_path], plugins=[("broken_pkg", "no_such_module_x")]) == 0
    assert "the commands of broken_pkg (no_such_module_x) are left out: " \
        "ModuleNotFoundError" in capsys.readouterr().err


def test_registered_modules_reads_rospack_and_survives_its_absence():
    class Done:
        returncode, stdout = 0, "pkg_b mod_b\npkg_a mod.a\n\n"
    assert registered_modules(lambda *a, **k: Done()) == [("pkg_a", "mod.a"), ("pkg_b", "mod_b")]

    def missing(*a, **k):
        raise FileNotFoundError("rospack")
    assert registered_modules(missing) == []


def test_unknown_options_of_other_commands_are_still_refused(testbed_path):
    with pytest.raises(SystemExit) as done:
        main(["check", testbed_path, "--runs", "1"])
    assert done.value.code == 2


def test_help_lists_the_commands_in_their_order(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--help"], plugins=[])
    assert done.value.code == 0
    out = capsys.readouterr().out
    listed = [line.split()[0] for line in out.splitlines()
              if line.startswith("    ") and not line.startswith("     ")]
    assert listed == ["check", "plan", "top", "model", "profile", "thresholds"]
