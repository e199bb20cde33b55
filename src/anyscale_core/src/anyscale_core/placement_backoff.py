"""Moves that failed, remembered (no ROS): a node sent back from a scale for rate or CPU, or
refused there for capacity by a shared scale's ledger, is not moved there again until something
changed that makes it likely to work (the scale's load dropped, or the live cost estimate says
it now fits where it did not), or, failing that, until a back-off that doubles with each
failure in a row has passed. A stay there that lasts resets it.
Keys are whatever identifies a move, e.g. (node, scale)."""
from dataclasses import dataclass
from typing import Dict, Hashable, List, Optional


@dataclass(frozen=True)
class PlacementBackoffParams:
    first_s: float = 10.0        # the first failure's back-off (the decision node gives it T)
    max_s: float = 300.0         # the doubling stops here; 0: no back-off of its own
    success_s: float = 60.0      # a stay this long without a failure resets the back-off
    retry_room: float = 10.0     # % of the scale: a load this much lower is worth a new try


@dataclass(frozen=True)
class Backoff:
    """A move that failed `failures` times in a row, the last at `at`."""
    failures: int
    at: float
    until: float                 # not tried again before this, unless something changed
    load: float                  # the scale's load then (% of its capacity, the node's not in)
    fitted: bool                 # the cost estimate then said the node fits there
    reason: str

    @property
    def delay_s(self) -> float:
        return self.until - self.at


class PlacementBackoff:
    """The back-offs of failed moves and the stays that may reset them, by move."""

    def __init__(self, params: PlacementBackoffParams = PlacementBackoffParams()):
        self.params = params
        self.backoffs: Dict[Hashable, Backoff] = {}
        self.stays: Dict[Hashable, float] = {}      # move -> since when the node is there

    def moved(self, key: Hashable, now: float):
        """The node of `key` now runs where `key` places it (moved there, or found there)."""
        self.stays[key] = now

    def failed(self, key: Hashable, now: float, load: float, fitted: bool,
               reason: str) -> Optional[Backoff]:
        """The node of `key` was sent back for rate or CPU; its back-off (None if off)."""
        self.stays.pop(key, None)
        if self.params.max_s <= 0:
            return None
        before = self.backoffs.get(key)
        failures = before.failures + 1 if before else 1
        delay = min(self.params.first_s * 2.0 ** (failures - 1), self.params.max_s)
        self.backoffs[key] = Backoff(failures, now, now + delay, load, fitted, reason)
        return self.backoffs[key]

    def left(self, key: Hashable):
        """The node of `key` left for another reason (the link, a crash): no failure, and its
        stay ends without counting as a success."""
        self.stays.pop(key, None)

    def settle(self, now: float) -> List[Hashable]:
        """The moves whose back-off a stay of success_s has reset since the last call."""
        reset = [k for k, since in self.stays.items()
                 if now - since >= self.params.success_s and k in self.backoffs]
        for key in reset:
            del self.backoffs[key]
        return reset

    def blocked(self, key: Hashable, now: float, load: float, fits: bool) -> bool:
        """Whether the move may not be tried now: it failed, its back-off runs, the scale's
        load (`load`, % of its capacity) has not dropped by retry_room since, and the cost
        estimate does not newly say it fits (`fits`: it fits now)."""
        b = self.backoffs.get(key)
        if b is None or not now < b.until:
            return False
        if load <= b.load - self.params.retry_room:
            return False
        return not (fits and not b.fitted)

    def retry_in(self, key: Hashable, now: float) -> float:
        """Seconds its back-off still runs (0 if none)."""
        b = self.backoffs.get(key)
        return max(0.0, b.until - now) if b is not None else 0.0

    def get(self, key: Hashable) -> Optional[Backoff]:
        return self.backoffs.get(key)


def ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


def describe(node: str, scale: str, b: Backoff, retry_room: float,
             refused: Optional[bool] = None) -> str:
    """The log line of a back-off: the reason and when the move may be tried again. refused:
    a shared scale refused a start for capacity, of this node (True) or of another (False)."""
    fits = "" if b.fitted else ", or once its cost estimate fits there"
    why = f"its {ordinal(b.failures)} return in a row for rate or CPU" if refused is None else \
        f"{'its' if refused else 'a'} start refused for capacity ({ordinal(b.failures)} in a row)"
    return (f"{node} -> {scale} backed off after {why} ({b.reason}): not tried again for "
            f"{b.delay_s:g} s, unless the load of {scale} drops {retry_room:g} points below "
            f"{b.load:.0f} %{fits}")
