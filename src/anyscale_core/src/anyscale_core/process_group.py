"""Processes started in a session of their own and ended as a group (pure Python): SIGINT to the
group, SIGKILL after a grace period, reaped either way. `anyscale thresholds` runs its throttle,
mux and subscriber this way; this package's live tests and the benches end what they start
with the same stop_process_group()."""
import os
import signal
import subprocess
from typing import List


def stop_process_group(proc: subprocess.Popen, grace_s: float):
    """SIGINT to `proc`'s process group (a ROS node shuts down cleanly on it), SIGKILL when it
    has not ended within grace_s; reaped either way, also when the group is gone already."""
    try:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    except ProcessLookupError:
        proc.wait()


def log_tail(path: str, lines: int = 3) -> str:
    """The last non-blank lines of a log file joined with " | "; "" when it cannot be read."""
    try:
        with open(path, errors="replace") as f:
            tail = [line.rstrip() for line in f.readlines()[-lines:] if line.strip()]
    except OSError:
        return ""
    return " | ".join(tail)


def _sigint_default():
    """In the child: SIGINT back to its default. A command run in the background (`&`, nohup)
    starts with SIGINT ignored, its children inherit that, and a stop's SIGINT then did nothing:
    each process was killed after the grace instead of shutting down."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class OwnProcess:
    """A process a command starts, in its own process group, its output in a log file."""

    def __init__(self, name: str, argv: List[str], log_dir: str, stop_grace_s: float = 5.0):
        self.name = name
        self.stop_grace_s = stop_grace_s
        self.log_path = os.path.join(log_dir, f"{name}.log")
        with open(self.log_path, "ab") as log:
            self.proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                         stdin=subprocess.DEVNULL, start_new_session=True,
                                         preexec_fn=_sigint_default)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def log_tail(self, lines: int = 3) -> str:
        return log_tail(self.log_path, lines)

    def stop(self):
        """The group ended (stop_process_group), unless the process has ended already."""
        if self.proc.poll() is None:
            stop_process_group(self.proc, self.stop_grace_s)
