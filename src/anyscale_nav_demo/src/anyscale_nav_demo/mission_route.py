"""The mission's route ahead (no ROS): the path from the robot to its current goal, then on
through the goals after it, as far as a length. A planner's plan ends at the current goal, and
what lies past it (the next leg, the next lap) is what a look-ahead along the route needs."""
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

Point = Tuple[float, float]


class MissionRoute:
    """`plan(goal_xy)` gives a planner to a goal: an object whose path_from(xy) returns the
    waypoints from xy to that goal, or None where it cannot be reached
    (costmap.NavigationFunction). Each goal's planner and each leg between two goals is made
    once: the map is static (a new map needs a new MissionRoute)."""

    def __init__(self, goals: Sequence[Sequence[float]], plan: Callable[[Point], object]):
        self.goals = [(float(g[0]), float(g[1])) for g in goals]
        self._plan = plan
        self._planners: Dict[Point, object] = {}
        self._legs: Dict[int, Optional[np.ndarray]] = {}

    def ahead(self, to_current: Optional[np.ndarray], index: int,
              max_length_m: float) -> Optional[np.ndarray]:
        """(n, 2) waypoints: `to_current` (the robot's path to goal `index`), then each leg to
        the goals after it, until the route is at least max_length_m long or the mission ends.
        A leg that cannot be planned ends the route there. None without a path to the current
        goal."""
        if to_current is None or len(to_current) == 0:
            return None
        parts = [np.asarray(to_current, dtype=float).reshape(-1, 2)]
        length = _length(parts[0])
        k = index
        while length < max_length_m and k + 1 < len(self.goals):
            leg = self._leg(k)
            if leg is None:
                break
            parts.append(leg[1:] if len(leg) > 1 else leg)
            length += _length(leg)
            k += 1
        return np.concatenate(parts)

    def planner(self, goal_xy: Sequence[float]):
        """The planner to a goal, made once per place (a loop's goals repeat)."""
        key = (float(goal_xy[0]), float(goal_xy[1]))
        if key not in self._planners:
            self._planners[key] = self._plan(key)
        return self._planners[key]

    def _leg(self, k: int) -> Optional[np.ndarray]:
        """The waypoints from goal k to goal k + 1."""
        if k not in self._legs:
            planner = self.planner(self.goals[k + 1])
            path = planner.path_from(self.goals[k]) if planner is not None else None
            self._legs[k] = None if path is None else np.asarray(path, dtype=float)
        return self._legs[k]


def _length(points: np.ndarray) -> float:
    return float(np.hypot(*np.diff(points, axis=0).T).sum()) if len(points) > 1 else 0.0
