"""process_group.py (no roscore): a process group ended by SIGINT, or by SIGKILL when it ignores
SIGINT, reaped either way (also when pytest runs in the background, where SIGINT starts ignored);
a log's last lines."""
import subprocess
import time

from anyscale_core.process_group import OwnProcess, log_tail, stop_process_group


def test_a_group_that_ignores_sigint_is_killed_and_reaped():
    proc = subprocess.Popen(["sh", "-c", "trap '' INT; sleep 30"], start_new_session=True)
    time.sleep(0.2)                                  # the trap is set
    started = time.monotonic()
    stop_process_group(proc, 0.3)
    assert proc.returncode == -9 and time.monotonic() - started < 5
    stop_process_group(proc, 0.3)                    # gone already: nothing raised


def test_an_own_process_logs_and_stops(tmp_path):
    proc = OwnProcess("talker", ["sh", "-c", "echo one; echo; echo two; exec sleep 30"],
                      str(tmp_path))
    time.sleep(0.3)
    assert proc.alive() and proc.log_tail() == "one | two"
    proc.stop()
    assert not proc.alive() and proc.proc.returncode == -2     # SIGINT ended it
    assert log_tail(str(tmp_path / "nothing.log")) == ""
