"""`anyscale thresholds --probe-script CMD`: the user's command as a correctness probe, run once
every period while a step is watched (pure Python: a thread and subprocess, no ROS). Exit 0
passes, 1 fails; any other exit, or none within the timeout, breaks the probe (ProbeBroken with
the command's last stderr line), which ends the run with one error line."""
import os
import shlex
import shutil
import subprocess
import threading
import time
from typing import Dict, List, Optional

from .model import ModelError
from .thresholds_search import ProbeBroken


class ScriptProbe:
    """The user's command, run once every `period_s` while open: exit 0 passes, 1 fails, any
    other exit (or no exit within the timeout) breaks the probe."""

    def __init__(self, command: str, period_s: float):
        try:
            self.argv = shlex.split(command)
        except ValueError as e:
            raise ModelError("--probe-script", "", f"cannot split {command!r}: {e}") from None
        if not self.argv:
            raise ModelError("--probe-script", "", "empty command")
        exe = self.argv[0]
        if not (shutil.which(exe) or (os.sep in exe and os.access(exe, os.X_OK))):
            raise ModelError("--probe-script", "", f"{exe}: not an executable (give a path or "
                                                   "a command on PATH)")
        self.description = f"script `{command}` every {period_s:g} s"
        self.period_s = period_s
        self.timeout_s = max(10.0, 5 * period_s)
        self._lock = threading.Lock()
        self._results: List[bool] = []
        self._broken: Optional[ProbeBroken] = None
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self.env: Dict[str, str] = dict(os.environ)

    def connect(self, tick):
        pass

    def _loop(self):
        while not self._stop.is_set():
            started = time.monotonic()
            try:
                run = subprocess.run(self.argv, capture_output=True, text=True,
                                     timeout=self.timeout_s, env=self.env)
            except subprocess.TimeoutExpired:
                self._fail(f"no exit within {self.timeout_s:g} s")
                return
            except OSError as e:
                self._fail(f"cannot run: {e.strerror}")
                return
            if run.returncode not in (0, 1):
                last = (run.stderr.strip().splitlines() or [""])[-1]
                self._fail(f"exit status {run.returncode} (0 = correct, 1 = not)"
                           + (f": {last}" if last else ""))
                return
            with self._lock:
                self._results.append(run.returncode == 0)
            self._stop.wait(max(0.0, self.period_s - (time.monotonic() - started)))

    def _fail(self, why: str):
        with self._lock:
            self._broken = ProbeBroken("--probe-script", "", f"{self.argv[0]}: {why}")

    def open(self):
        with self._lock:
            self._results = []
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, daemon=True, name="probe script")
        self._thread.start()

    def close(self):
        """(passed, checks, None); ProbeBroken if the command broke."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(self.timeout_s + 1)
        self.check_broken()
        with self._lock:
            return sum(self._results), len(self._results), None

    def check_broken(self):
        with self._lock:
            if self._broken is not None:
                raise self._broken

    def unregister(self):
        self._stop.set()
