"""Navigation's recovery when every trajectory collides: turn in place, as move_base's
rotate_recovery does, so that the localisation sees the walls from every side again.

Why it is needed here: a stopped robot gives AMCL nothing to update on (update_min_d and
update_min_a are not reached), so an estimate that drifted into a wall stays there and the
planner keeps finding every trajectory in collision. In a tolerance bench run the robot stood
for 1,000 s this way after a 1.25 m jump of the estimate. A full turn of a round base sweeps
only the disc it stands on, so it is safe wherever the robot truly is.

No ROS: the navigation node feeds it, once per control period, whether the local planner found
a free trajectory and the current yaw, and it says whether to turn in place instead.
"""
import math
from dataclasses import dataclass
from typing import Optional

from .geometry import wrap_angle

FREE, TURNING, GAVE_UP = "free", "turning", "gave_up"


@dataclass(frozen=True)
class RecoveryConfig:
    stuck_after_s: float = 3.0    # every trajectory colliding this long starts a turn
    turn_rad: float = 2 * math.pi  # how far one recovery turns
    attempts: int = 3             # turns in a row (no free trajectory between) before giving up
    # A turn not done by then ends anyway (counted as an attempt): the robot may be held, or its
    # yaw not seen to change, and a recovery must not turn for ever.
    turn_timeout_s: float = 30.0


class RotateRecovery:
    def __init__(self, cfg: RecoveryConfig = RecoveryConfig()):
        self.cfg = cfg
        self.state = FREE
        self.blocked_since: Optional[float] = None
        self.turned = 0.0
        self.last_yaw = 0.0
        self.attempt = 0              # recovery turns since the planner last found a free path
        self.turn_started = 0.0

    def step(self, now: float, blocked: Optional[bool], yaw: float) -> str:
        """The state after this control period: TURNING (turn in place, counter-clockwise, at
        the allowed rate), GAVE_UP (stop: `attempts` turns did not free the way), or FREE (plan
        as usual). `blocked`: whether the local planner found every trajectory colliding;
        None while turning, when the planner is not asked."""
        if self.state == TURNING:
            self.turned += abs(float(wrap_angle(yaw - self.last_yaw)))
            self.last_yaw = yaw
            if self.turned < self.cfg.turn_rad and \
                    now - self.turn_started < self.cfg.turn_timeout_s:
                return TURNING
            self.state, self.blocked_since = FREE, now   # a new window to find a free path
            return FREE
        if not blocked:
            self.state, self.blocked_since, self.attempt = FREE, None, 0
            return FREE
        if self.blocked_since is None:
            self.blocked_since = now
        if now - self.blocked_since < self.cfg.stuck_after_s:
            return self.state
        if self.attempt >= self.cfg.attempts:
            self.state = GAVE_UP
            return GAVE_UP
        self.attempt += 1
        self.state, self.turned, self.last_yaw, self.turn_started = TURNING, 0.0, yaw, now
        return TURNING
