"""When a node that ended unasked may be started again: at once the first time, then after
delays that double up to a limit, and at once again once it has run long enough.

roslaunch's respawn waits a fixed `respawn_delay` every time and rosmon's respawn a fixed
delay too; neither fits here. The first restart must be at once, because the node's subscribers
have a tolerance of one or two seconds. A node that keeps failing (a bad parameter, a missing
input) must not be restarted many times a second for ever.
"""
import math
from dataclasses import dataclass

from .param_spec import declared


@dataclass(frozen=True)
class BackoffParams:
    first_delay_s: float = declared(
        1.0, "a node that ended unasked starts again at once, then after this, doubling", "s",
        name="restart_delay_s", minimum=0.0)
    max_delay_s: float = declared(30.0, "the doubling stops here", "s",
                                  name="restart_delay_max_s", minimum=0.0)
    reset_after_s: float = declared(
        30.0, "a node that ran this long since its last restart starts over at once", "s",
        name="restart_reset_s", minimum=0.0)


class RestartBackoff:
    """One node's restart schedule. The engine asks `due` on every tick while the node is seen
    ended, and says `restarted` when it starts it again."""

    def __init__(self, params: BackoffParams):
        self.params = params
        self.restarts_in_a_row = 0
        self.last_restart = -math.inf
        self.seen_ended_at = None          # first tick that saw the current end

    def delay_s(self) -> float:
        """How long after the previous restart the next one may come."""
        if self.restarts_in_a_row == 0:
            return 0.0
        return min(self.params.first_delay_s * 2 ** (self.restarts_in_a_row - 1),
                   self.params.max_delay_s)

    def due(self, now: float) -> bool:
        """Whether the node, seen ended at `now`, may be started again now."""
        if self.seen_ended_at is None:
            self.seen_ended_at = now
            if now - self.last_restart >= self.params.reset_after_s:
                self.restarts_in_a_row = 0      # it ran long enough: not a failure loop
        return now - self.last_restart >= self.delay_s()

    def restarted(self, now: float):
        self.restarts_in_a_row += 1
        self.last_restart = now
        self.seen_ended_at = None
