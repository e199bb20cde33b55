"""Navigation's mission: visit the marker goals in order, recognising each marker, then return."""
import math

from .geometry import wrap_angle

DRIVE, FACE_MARKER, WAIT_MARKER, DONE = "drive", "face_marker", "wait_marker", "done"


def loop_from_goal(goals, k):
    """Where the robot starts, and its goals, for a run that starts at goal k of a loop: at
    goal k's pose, then the goals after it in order and round to goal k itself, so the loop is
    still complete. (A world's last goal is its start, so k = len - 1 is the usual run.)"""
    goals = [tuple(g) for g in goals]
    if not 0 <= k < len(goals):
        raise ValueError("goal %d: the loop has goals 0-%d" % (k, len(goals) - 1))
    return goals[k][:3], goals[k + 1:] + goals[:k + 1]


class GoalSequence:
    """Goals [(x, y, yaw, marker_id or -1)]. A marker goal is done once its marker was
    recognised (on the way, or after facing it at the goal, waiting at most marker_timeout);
    the others when the position is within xy_tolerance."""

    def __init__(self, goals, xy_tolerance=0.3, yaw_tolerance=0.2, marker_timeout=5.0):
        self.goals = [tuple(g) for g in goals]
        self.xy_tol, self.yaw_tol, self.marker_timeout = xy_tolerance, yaw_tolerance, marker_timeout
        self.index = 0
        self.state = DRIVE if self.goals else DONE
        self.seen = set()
        self.wait_started = None
        self.missed = []            # marker goals left after a timeout, unrecognised
        self.reached_times = []
        self.reported = None        # the status line last handed out by status_change()

    @property
    def current(self):
        return self.goals[self.index] if self.state != DONE else None

    def status(self):
        """The status line navigation publishes: state and goals done, e.g. "drive 2/5"."""
        return "%s %d/%d" % (self.state, self.index, len(self.goals))

    def status_change(self):
        """The status line if it changed since the last call, else None. The controller steps
        at 10 Hz, and a status sent on every step reached its listeners (the test bed's
        monitor printed "navigation: done 5/5") once per step; the topic is latched, so a
        listener that joins later still gets the current line."""
        line = self.status()
        if line == self.reported:
            return None
        self.reported = line
        return line

    def marker_seen(self, marker_id):
        self.seen.add(int(marker_id))

    def step(self, pose, now):
        """Advance the state for the robot pose; returns the state."""
        if self.state == DONE:
            return DONE
        gx, gy, gyaw, marker = self.current
        marker = int(marker)
        near = math.hypot(gx - pose[0], gy - pose[1]) < self.xy_tol
        if self.state == DRIVE and near:
            if marker < 0 or marker in self.seen:
                return self._next(now)
            self.state = FACE_MARKER
        if self.state == FACE_MARKER:
            if marker in self.seen:
                return self._next(now)
            if abs(float(wrap_angle(gyaw - pose[2]))) < self.yaw_tol:
                self.state, self.wait_started = WAIT_MARKER, now
        if self.state == WAIT_MARKER:
            if marker in self.seen:
                return self._next(now)
            if now - self.wait_started > self.marker_timeout:
                self.missed.append(marker)
                return self._next(now)
        return self.state

    def _next(self, now):
        self.reached_times.append(now)
        self.index += 1
        self.state = DRIVE if self.index < len(self.goals) else DONE
        return self.state
