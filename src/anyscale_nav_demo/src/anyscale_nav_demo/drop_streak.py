"""Streaks of dropped inputs (AMCL's scans with no odometry for their time), so that each
streak is logged twice, when it starts and when it ends with its count and length: a throttled
warning every 5 s hid how many scans a stall at home cost."""
from typing import Optional, Tuple


class DropStreak:
    def __init__(self):
        self.total = 0                     # every drop since the start
        self._count = 0                    # drops in the current streak
        self._first_t: Optional[float] = None
        self._last_t: Optional[float] = None

    def dropped(self, t: float) -> bool:
        """One more drop at time t; True if it starts a streak (the moment to say so)."""
        self.total += 1
        self._count += 1
        self._last_t = t
        if self._first_t is None:
            self._first_t = t
            return True
        return False

    def used(self) -> Optional[Tuple[int, float]]:
        """An input was used again: (drops, seconds from the first drop to the last) of the
        streak this ends, or None if there was none."""
        if self._first_t is None:
            return None
        streak = (self._count, self._last_t - self._first_t)
        self._count, self._first_t, self._last_t = 0, None, None
        return streak
