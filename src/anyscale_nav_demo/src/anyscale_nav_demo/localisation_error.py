"""A pose estimate's error against the simulator's ground truth (pure; node
nodes/localisation_error): the truth interpolated at the estimate's own time stamp, so an
estimate that arrives late is judged against where the robot was when its scan was taken, not
where it is now. Used as `anyscale thresholds`' correctness probe for laser -> AMCL."""
import bisect
import math
from collections import deque
from typing import Optional, Tuple


class TruthBuffer:
    """The last `horizon_s` of ground-truth poses (t, x, y, yaw), time-ordered."""

    def __init__(self, horizon_s: float = 10.0):
        self.horizon_s = horizon_s
        self._poses = deque()

    def add(self, t: float, x: float, y: float, yaw: float):
        if self._poses and t <= self._poses[-1][0]:
            return          # out of order or repeated: the buffer stays sorted
        self._poses.append((t, x, y, yaw))
        while self._poses and self._poses[0][0] < t - self.horizon_s:
            self._poses.popleft()

    def at(self, t: float) -> Optional[Tuple[float, float, float]]:
        """(x, y, yaw) at time t, linearly interpolated; None outside the buffer."""
        poses = list(self._poses)
        if not poses or t < poses[0][0] or t > poses[-1][0]:
            return None
        i = bisect.bisect_left([p[0] for p in poses], t)
        if poses[i][0] == t:
            return poses[i][1:]
        (t0, x0, y0, a0), (t1, x1, y1, a1) = poses[i - 1], poses[i]
        f = (t - t0) / (t1 - t0)
        turn = math.atan2(math.sin(a1 - a0), math.cos(a1 - a0))
        return x0 + f * (x1 - x0), y0 + f * (y1 - y0), a0 + f * turn


def position_error(estimate: Tuple[float, float], truth: Tuple[float, float, float]) -> float:
    return math.hypot(estimate[0] - truth[0], estimate[1] - truth[1])
