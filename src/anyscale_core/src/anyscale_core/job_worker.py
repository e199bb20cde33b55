"""A background thread that runs submitted jobs one at a time, in order; no ROS.

Used where a node must not wait for something slow: the decision node's calls to the agents
(one worker per node and per scale, agent_client.Worker) and AMCL's saving of its estimate to
the parameter server (seven calls, 0.08-0.31 s on the robot's quota, which the next scan waited
for). A job submitted with a key replaces the pending job of that key, so only the latest
lease renewal, watch list or pose is sent, however far behind the thread is.
"""
import collections
import logging
import threading
from typing import Callable, Hashable, Optional

OnError = Callable[[Exception, Optional[Hashable]], None]


class JobWorker:
    """submit() returns at once; one daemon thread runs the jobs in the order they were
    submitted. A keyed job replaces the pending (not yet started) job of the same key and
    takes its place at the back of the queue; a job already running is not affected. A job
    that raises is handed to on_error(exception, key) (key None for an unkeyed job), and the
    thread goes on with the next one.

    The thread is a daemon: it ends with the process, and a caller need not stop it.
    close() lets it run what is pending and end."""

    def __init__(self, name: str, on_error: OnError):
        self._on_error = on_error
        # internal key -> (caller's key, job); an unkeyed job gets a key of its own that no
        # caller's key can equal
        self._jobs: "collections.OrderedDict[Hashable, tuple]" = collections.OrderedDict()
        self._cond = threading.Condition()
        self._closing = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, job: Callable[[], None], key: Optional[Hashable] = None):
        with self._cond:
            if self._closing:
                raise RuntimeError(f"{self._thread.name}: submit() after close()")
            internal = object() if key is None else key
            self._jobs.pop(internal, None)
            self._jobs[internal] = (key, job)
            self._cond.notify()

    def pending(self) -> int:
        """Jobs submitted and not yet started."""
        with self._cond:
            return len(self._jobs)

    def close(self, timeout_s: Optional[float] = None) -> bool:
        """Runs what is pending, then ends the thread; later submits raise RuntimeError. Waits
        up to timeout_s (None: until it ended) and says whether the thread ended."""
        with self._cond:
            self._closing = True
            self._cond.notify()
        self._thread.join(timeout_s)
        return not self._thread.is_alive()

    def _run(self):
        while True:
            with self._cond:
                while not self._jobs and not self._closing:
                    self._cond.wait()
                if not self._jobs:
                    return
                _, (key, job) = self._jobs.popitem(last=False)
            try:
                job()
            except Exception as e:  # noqa: BLE001 - one failed job must not end the worker
                try:
                    self._on_error(e, key)
                except Exception:  # noqa: BLE001 - nor a failed report of it
                    logging.getLogger(__name__).exception(
                        "%s: on_error failed on %r", self._thread.name, e)
