"""The monitor's periodic saves of its record, written by a forked child at a low priority, so
that a save never delays the monitor's receive threads, whose arrival times the silences are
judged by (docs/measurements/fault_soak.md, 2026-12-02). A killed run still leaves its latest
record."""
import os
from typing import Optional

from .testbed_record import TestbedRecord

CHILD_NICE = 10     # below every process of the test bed: the save yields the CPU to them


class BackgroundSaver:
    def __init__(self, path: str):
        self.path = path
        self.child: Optional[int] = None

    def busy(self) -> bool:
        """Whether the child of the previous save is still writing."""
        if self.child is None:
            return False
        pid, _ = os.waitpid(self.child, os.WNOHANG)
        if pid == 0:
            return True
        self.child = None
        return False

    def start(self, copy: TestbedRecord) -> bool:
        """Writes `copy` (a snapshot: nothing may change it) to the path from a child, whole or
        not at all (through a temporary file). False, and nothing written, while the previous
        save is still writing."""
        if self.busy():
            return False
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                os.nice(CHILD_NICE)
                _write(copy, self.path)
                code = 0
            finally:
                os._exit(code)     # no atexit or ROS shutdown hooks of the parent in the child
        self.child = pid
        return True

    def finish(self, last: TestbedRecord):
        """Waits for a save still writing, then writes `last` in this process: no late child
        can replace it."""
        if self.child is not None:
            os.waitpid(self.child, 0)
            self.child = None
        _write(last, self.path)


def _write(rec: TestbedRecord, path: str):
    tmp = f"{path}.{os.getpid()}.tmp"
    rec.save(tmp)
    os.replace(tmp, path)
