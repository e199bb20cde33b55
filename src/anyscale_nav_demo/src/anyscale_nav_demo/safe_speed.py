"""Navigation's safe-speed rule: speed follows the rate and age of localisation corrections.

Between two corrections the robot moves on dead reckoning alone. Bounding the distance it may
travel between corrections by d_max gives v_max = d_max * f, where f is the correction rate,
or 1 / age once the current correction is overdue. With d_max = 0.1 m, AMCL at its optimal
5 Hz allows 0.5 m/s (capped at the robot's 0.4 m/s) and at its minimum 2 Hz only 0.2 m/s,
as the paper measured; past the tolerance (no correction for timeout s) the robot stops.
"""
import collections


def safe_speed_limit(rate, age, max_speed, max_dead_reckoning, timeout):
    """Speed (m/s) allowed with corrections at `rate` Hz, the last one `age` s old."""
    if rate is None or age is None or age > timeout or rate <= 0:
        return 0.0
    f = rate if age <= 0 else min(rate, 1.0 / age)
    return min(max_speed, max_dead_reckoning * f)


class CorrectionMonitor:
    """Arrival times of localisation corrections, for their rate and the age of the last one."""

    def __init__(self, window=3.0):
        self.window = window
        self.times = collections.deque()

    def add(self, t):
        self.times.append(t)
        while len(self.times) > 2 and self.times[-1] - self.times[0] > self.window:
            self.times.popleft()

    def rate(self):
        """Mean rate over the window (Hz), None before two corrections arrived."""
        if len(self.times) < 2 or self.times[-1] <= self.times[0]:
            return None
        return (len(self.times) - 1) / (self.times[-1] - self.times[0])

    def age(self, now):
        return None if not self.times else now - self.times[-1]

    def clear(self):
        self.times.clear()
