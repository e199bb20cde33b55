"""`anyscale thresholds`' report and model edit, and its script probe (no roscore): the text and
JSON of a run, freq_min / freq_opt / tolerance written into the relay model with every other
line kept, a probe script's verdicts and its breaking."""
import os
import shutil
import time

import pytest
import yaml

from anyscale_core.model import ModelError
from anyscale_core.script_probe import ScriptProbe
from anyscale_core.thresholds_report import ThresholdsRun, summary_line, write_into_model
from anyscale_core.thresholds_search import ProbeBroken, StepResult, thresholds

RELAY_MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "config",
                           "relay_model.yaml")
QUOTA = 0.95


def relay_run() -> ThresholdsRun:
    steps = [StepResult(10.0, 0.0, 20, 20, None, 10.0), StepResult(5.0, 0.0, 20, 20, None, 5.0),
             StepResult(2.0, 0.0, 3, 20, None, 2.0), StepResult(10.0, 0.5, 22, 22, None, 9.5),
             StepResult(10.0, 1.0, 10, 22, None, 9.1)]
    found = thresholds(steps[:3], steps[3:], QUOTA, 0.1)
    return ThresholdsRun("talker", "relay", "/chatter", 10.004, "script `ok` every 1 s",
                         QUOTA, steps, found)


def test_a_run_as_json_and_as_text():
    run = relay_run()
    report = run.as_json(written=False)
    assert (report["freq_min"], report["freq_opt"], report["tolerance"]) == (5.0, 5.0, 0.5)
    assert report["connection"] == "talker:relay:/chatter" and report["source_hz"] == 10.004
    assert [s["correct"] for s in report["steps"]] == [True, True, False, True, False]
    assert report["written"] is False
    lines = run.text_lines("relay.yaml", written=False)
    assert lines[0] == "talker -> relay on /chatter: source 10.00 Hz; probe script `ok` every 1 s"
    assert lines[3] == "  2 Hz: delivered 2.00 Hz; probe passed 3 of 20: NOT correct"
    assert lines[-2] == summary_line(run.found) == \
        "freq_min 5 Hz, freq_opt 5 Hz, tolerance 0.5 s"
    assert lines[-1] == "relay.yaml: not changed (--dry-run)"


def test_a_tolerance_not_measured_is_said_and_left_in_the_model(tmp_path):
    """The subscriber did not work again after the failed rate step: no interruption tried."""
    steps = relay_run().steps[:3]
    why = "relay did not work again within 60 s at 5 Hz after the incorrect step at 2 Hz"
    found = thresholds(steps, [], QUOTA, 0.1, unmeasured=why)
    run = ThresholdsRun("talker", "relay", "/chatter", 10.004, "script `ok` every 1 s", QUOTA,
                        steps, found)
    assert summary_line(found) == f"freq_min 5 Hz, freq_opt 5 Hz, tolerance not measured: {why}"
    report = run.as_json(written=True)
    assert report["tolerance"] is None and report["tolerance_unmeasured"] == why
    model = tmp_path / "relay_model.yaml"
    shutil.copy(RELAY_MODEL, model)
    write_into_model(str(model), run, "2026-11-24 12:10")
    connection = next(c for c in yaml.safe_load(model.read_text())["connections"]
                      if c["subscriber"] == "relay")
    assert (connection["freq_min"], connection["freq_opt"], connection["tolerance"]) == \
        (5, 5, 2)                               # the model's tolerance (2 s) kept
    assert "tolerance not measured: relay did not work again" in model.read_text()


def test_written_into_the_connection_with_every_other_line_kept(tmp_path):
    model = tmp_path / "relay_model.yaml"
    shutil.copy(RELAY_MODEL, model)
    before = model.read_text()
    write_into_model(str(model), relay_run(), "2026-11-24 01:04")
    text = model.read_text()
    connection = next(c for c in yaml.safe_load(text)["connections"]
                      if c["subscriber"] == "relay")
    assert (connection["freq_min"], connection["freq_opt"], connection["tolerance"]) == \
        (5, 5, 0.5)
    assert "# thresholds: 2026-11-24 01:04 by `anyscale thresholds`: /chatter (10.00 Hz)" in text
    kept = [line for line in before.splitlines() if "subscriber: relay," not in line
            and "tolerance: 2, bandwidth_mbps: 0.01}" not in line]
    assert all(line in text.splitlines() for line in kept)


def test_a_probe_script_passes_and_fails_by_its_exit(tmp_path):
    for command, passed in (("true", True), ("false", False)):
        probe = ScriptProbe(command, 0.05)
        probe.open()
        time.sleep(0.3)
        ok, checks, value = probe.close()
        assert checks >= 2 and ok == (checks if passed else 0) and value is None


def test_a_probe_script_that_breaks_or_cannot_run(tmp_path):
    script = tmp_path / "probe.sh"
    script.write_text("#!/bin/sh\necho 'cannot reach the robot' >&2\nexit 3\n")
    script.chmod(0o755)
    probe = ScriptProbe(str(script), 0.05)
    probe.open()
    time.sleep(0.3)
    with pytest.raises(ProbeBroken, match="exit status 3 .*: cannot reach the robot"):
        probe.close()
    with pytest.raises(ModelError, match="not an executable"):
        ScriptProbe("no-such-probe-command", 1.0)
    with pytest.raises(ModelError, match="empty command"):
        ScriptProbe("  ", 1.0)
