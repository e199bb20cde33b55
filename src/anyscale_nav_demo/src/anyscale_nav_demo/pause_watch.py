"""Noticing that this process did not run for a while: paused with SIGSTOP (AnyScale's
launch.pause_at_home keeps a node's instance on the robot paused while another scale runs it),
or starved as badly. A node's state and the data in its socket buffers are then stale.

No ROS: a thread that checks every period, and the node's callbacks that check too, so that
whichever runs first after the pause sees it.
"""
import threading
import time
from typing import Callable


class PauseWatch:
    def __init__(self, gap_s: float, on_pause: Callable[[float], None],
                 clock: Callable[[], float] = time.monotonic):
        self.gap_s = gap_s
        self.on_pause = on_pause
        self.clock = clock
        self.awake = clock()
        self.lock = threading.Lock()

    def check(self) -> float:
        """How long the pause that just ended lasted (s), or 0.0 if there was none. Each pause
        is reported once, to on_pause(gap), by whichever caller checks first."""
        with self.lock:
            now = self.clock()
            gap, self.awake = now - self.awake, now
        if gap <= self.gap_s:
            return 0.0
        self.on_pause(gap)
        return gap

    def watch(self, period_s: float, running: Callable[[], bool]):
        """Checks every period_s while running()."""
        while running():
            time.sleep(period_s)
            self.check()


class ResumeStages:
    """When each stage of a node's return to work after a pause was first reached, as offsets
    from the resume, for one log line once the first output is out. A return that broke a
    tolerance left only its start and its end in the logs, not where the time between went."""

    def __init__(self, resumed_at: float):
        self.resumed_at = resumed_at
        self.reached = {}           # stage -> seconds after the resume, first time only

    def mark(self, stage: str, t: float):
        self.reached.setdefault(stage, t - self.resumed_at)

    def summary(self) -> str:
        """'tf +0.31 s, fresh scan +0.40 s, ...' in the order the stages were reached."""
        return ", ".join("%s +%.2f s" % (stage, dt)
                         for stage, dt in sorted(self.reached.items(), key=lambda kv: kv[1]))
