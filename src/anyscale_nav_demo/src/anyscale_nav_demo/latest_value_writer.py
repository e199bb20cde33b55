"""Writing a node's latest value somewhere slow (the parameter server) off its critical path.

No ROS: the write function is given. AMCL saves its estimate to its ~initial_pose_* parameters
every 2 s, seven parameter-server calls; on the robot's quota those took 0.08 s (median; up to
0.31 s) between the first and the last reaching the master, and the next scan waited for them.

anyscale_core.agent_client.Worker does the same for the decision node (a keyed job replaces a
pending one), but it lives with the agents' service calls and logs as the decision node; it
should move to a ROS-free module of its own that both use (not done yet).
"""
import threading
from typing import Any, Callable, Optional


class LatestValueWriter:
    """offer(value) returns at once; a thread writes the latest value offered, so a value
    offered while an earlier one is being written replaces any not yet written."""

    def __init__(self, write: Callable[[Any], None], on_error: Callable[[Exception], None]):
        self._write = write
        self._on_error = on_error
        self._cond = threading.Condition()
        self._pending: Optional[Any] = None
        self._has_pending = False
        self._stopping = False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def offer(self, value: Any):
        with self._cond:
            self._pending, self._has_pending = value, True
            self._cond.notify()

    def stop(self, timeout_s: float = 1.0):
        """Writes what is pending, then ends the thread (waiting up to timeout_s)."""
        with self._cond:
            self._stopping = True
            self._cond.notify()
        self._thread.join(timeout_s)

    def _run(self):
        while True:
            with self._cond:
                while not self._has_pending and not self._stopping:
                    self._cond.wait()
                if not self._has_pending:
                    return
                value, self._pending, self._has_pending = self._pending, None, False
            try:
                self._write(value)
            except Exception as e:  # noqa: BLE001 - the node decides what a failed write means
                self._on_error(e)
