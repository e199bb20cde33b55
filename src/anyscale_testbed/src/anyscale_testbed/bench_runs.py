"""How the benches and root tests run processes: scripts/run_testbed.py once, in a session of
its own with its console in a file and Ctrl-C passed on as one SIGTERM (so that the run removes
its test bed); the newest record.json below a run's directory; a node stopped as Ctrl-C would."""
import glob
import os
import signal
import subprocess
import sys
from typing import List, Optional

from .testbed_record import TestbedRecord
from .two_scale_testbed import missing_capabilities


def interrupt_on_sigterm():
    """A plain kill ends a bench as Ctrl-C does: the run in progress tears its test bed down
    and the bench prints the runs that ended. (A bench started in the background of a
    non-interactive shell ignores SIGINT, so SIGTERM is how it is stopped there.)"""
    def raise_interrupt(*_):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, raise_interrupt)


def start_on_the_testbed(program: str):
    """What a bench does first: SIGTERM ends it as Ctrl-C does, and it ends with one line if
    this machine cannot run the test bed."""
    interrupt_on_sigterm()
    missing = missing_capabilities()
    if missing:
        sys.exit(f"{program}: the test bed needs " + "; ".join(missing))


def run_logged(argv: List[str], out_dir: str) -> int:
    """Runs argv with its output in out_dir/console.log; returns its exit code. A session of
    its own: Ctrl-C reaches the bench only, which passes exactly one SIGTERM on and waits for
    the run's teardown (killing the run would leave its test bed behind)."""
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "console.log"), "wb") as log:
        proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
        try:
            return proc.wait()
        except KeyboardInterrupt:
            # SIGTERM, not SIGINT: a bench started in the background ignores SIGINT, and so
            # does the run it starts (an ignored signal stays ignored across exec).
            # run_testbed.py tears its test bed down on either.
            proc.send_signal(signal.SIGTERM)
            _wait_through_interrupts(proc)
            raise


def _wait_through_interrupts(proc: subprocess.Popen):
    while True:
        try:
            proc.wait()
            return
        except KeyboardInterrupt:
            print("bench: still removing the test bed of the run ...", flush=True)


def interrupt_then_kill(proc: subprocess.Popen, timeout_s: float):
    """Ctrl-C for one process (a ROS node shuts down cleanly on it), SIGKILL after timeout_s."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def save_table(table: str, out_dir: str, name: str):
    """A bench's closing table: printed, and written to out_dir/name."""
    print(table)
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, name)
    with open(path, "w") as f:
        f.write(table + "\n")
    print(f"bench: {path}")


def latest_record(out_dir: str) -> Optional[TestbedRecord]:
    """The newest run's record below out_dir, None if there is none, it is unreadable, or its
    run did not end by itself: killed before its monitor ended (no finished_t: the monitor
    saves every 5 s, so a run killed 4 minutes in leaves a record of 4 minutes) or stopped by
    Ctrl-C or SIGTERM (`interrupted`). Such a record is no result to resume from."""
    found = sorted(glob.glob(os.path.join(out_dir, "*", "record.json")))
    if not found:
        return None
    try:
        rec = TestbedRecord.load(found[-1])
    except (OSError, ValueError, TypeError, KeyError) as e:
        print(f"bench: {found[-1]}: unreadable record ({e})", flush=True)
        return None
    if rec.finished_t is None or rec.interrupted:
        print(f"bench: {found[-1]}: its run was stopped before it ended", flush=True)
        return None
    return rec
