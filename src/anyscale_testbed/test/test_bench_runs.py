"""The benches' run helper: console captured, exit code passed on, newest record read."""
import os
import sys

from anyscale_testbed.bench_runs import interrupt_then_kill, latest_record, run_logged
from anyscale_testbed.testbed_record import TestbedRecord, mark_interrupted


def test_run_logged_keeps_the_console_and_the_exit_code(tmp_path):
    code = run_logged([sys.executable, "-c", "import sys; print('hello'); "
                       "print('oops', file=sys.stderr); sys.exit(3)"], str(tmp_path / "run"))
    assert code == 3
    text = (tmp_path / "run" / "console.log").read_text()
    assert "hello" in text and "oops" in text


def test_latest_record_is_the_newest_and_none_when_missing_or_broken(tmp_path, capsys):
    assert latest_record(str(tmp_path)) is None
    for stamp, world in (("20261123-100000", "old"), ("20261123-110000", "new")):
        os.makedirs(tmp_path / f"office_floor-{stamp}")
        TestbedRecord(world=world, finished_t=400.0).save(
            str(tmp_path / f"office_floor-{stamp}" / "record.json"))
    assert latest_record(str(tmp_path)).world == "new"
    os.makedirs(tmp_path / "office_floor-20261123-120000")
    (tmp_path / "office_floor-20261123-120000" / "record.json").write_text("{not json")
    assert latest_record(str(tmp_path)) is None
    assert "unreadable record" in capsys.readouterr().out


def test_a_run_killed_or_interrupted_before_it_ended_is_no_record(tmp_path, capsys):
    path = tmp_path / "office_floor-20261127-025304" / "record.json"
    os.makedirs(path.parent)
    TestbedRecord(world="killed", finished_t=None).save(str(path))
    assert latest_record(str(tmp_path)) is None
    assert "stopped before it ended" in capsys.readouterr().out
    TestbedRecord(world="ended", finished_t=117.3).save(str(path))
    assert latest_record(str(tmp_path)).world == "ended"
    mark_interrupted(str(path))
    assert latest_record(str(tmp_path)) is None
    assert TestbedRecord.load(str(path)).interrupted


def test_interrupt_then_kill_ends_a_process_that_ignores_ctrl_c():
    import subprocess
    proc = subprocess.Popen([sys.executable, "-c", "import signal, time; "
                             "signal.signal(signal.SIGINT, signal.SIG_IGN); print(1, flush=True); "
                             "time.sleep(30)"], stdout=subprocess.PIPE)
    proc.stdout.readline()                  # the SIGINT handler is in place
    interrupt_then_kill(proc, 0.2)
    assert proc.returncode == -9


def test_sigterm_interrupts_like_ctrl_c():
    import subprocess
    code = ("import os, signal, time, sys\n"
            "from anyscale_testbed.bench_runs import interrupt_on_sigterm\n"
            "interrupt_on_sigterm()\n"
            "try:\n"
            "    os.kill(os.getpid(), signal.SIGTERM); time.sleep(5)\n"
            "except KeyboardInterrupt:\n"
            "    sys.exit(42)\n")
    assert subprocess.run([sys.executable, "-c", code], timeout=10).returncode == 42


def test_an_interrupted_bench_ends_its_run_even_where_sigint_is_ignored(tmp_path):
    """A bench in the background of a non-interactive shell ignores SIGINT, and so does the run
    it starts; SIGTERM reaches both."""
    import signal
    import subprocess
    import time
    run = ("import signal, sys, time\n"
           "def bye(*_):\n"
           "    print('torn down', flush=True); sys.exit(0)\n"
           "signal.signal(signal.SIGTERM, bye)\n"
           "print('running', flush=True)\n"
           "time.sleep(30)\n")
    bench = ("import sys\n"
             "from anyscale_testbed.bench_runs import interrupt_on_sigterm, run_logged\n"
             "interrupt_on_sigterm()\n"
             "try:\n"
             f"    run_logged([sys.executable, '-c', {run!r}], {str(tmp_path)!r})\n"
             "except KeyboardInterrupt:\n"
             "    sys.exit(130)\n")
    proc = subprocess.Popen([sys.executable, "-c", bench],
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    log = tmp_path / "console.log"
    deadline = time.monotonic() + 10
    while (time.monotonic() < deadline
           and "running" not in (log.read_text() if log.exists() else "")):
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=10) == 130
    assert "torn down" in log.read_text()
