"""The mission's ground truth as steps, with the link and AMCL's place at each (pure, no ROS):
what the coverage bound (evaluation_figures.py) and the shortfall by cause
(evaluation_shortfall.py) are both computed on."""
from dataclasses import dataclass
import math
from typing import List, Optional, Sequence, Tuple

import numpy as np

from anyscale_nav_demo.results import AMCL_ON_LAPTOP, BOTH_ON_LAPTOP, configuration_of

from .testbed_record import TestbedRecord, mapping_at
from .tolerance_report import path_time

# The safe-speed rule (anyscale_nav_demo/safe_speed.py: 0.1 m between corrections): AMCL at
# its optimal 5 Hz on the laptop allows 0.5 m/s, capped at the robot's 0.4 m/s; at its
# minimum 2 Hz on the robot, 0.2 m/s (the paper's two speeds).
FAST_MPS = 0.4
SLOW_MPS = 0.2
# A step slower than this is a stop or a turn on the spot, not driving; a case driven less
# than MIN_DRIVEN_M has no speed of its own worth measuring.
MIN_DRIVING_MPS = 0.05
MIN_DRIVEN_M = 5.0
AMCL_OUT = (AMCL_ON_LAPTOP, BOTH_ON_LAPTOP)


def path_window(rec: TestbedRecord) -> Tuple[float, float]:
    """(start, end) of the mission: navigation's first status to its "done", or to the record's
    last truth sample when the loop was not completed (or no status came)."""
    end = rec.truth[-1][0] if rec.truth else (rec.finished_t or 0.0)
    if not rec.navigation_status:
        return (rec.truth[0][0] if rec.truth else 0.0), end
    start = rec.navigation_status[0][0]
    duration = path_time(rec)
    return start, (start + duration if math.isfinite(duration) else end)


Window = Optional[Tuple[float, float]]


def truth_in_window(rec: TestbedRecord, window: Window = None) -> np.ndarray:
    """(N, 3) t, x, y of the ground truth within the mission (or `window`, e.g. a lap)."""
    start, end = window or path_window(rec)
    truth = np.asarray(rec.truth, dtype=float).reshape(-1, 3)
    return truth[(truth[:, 0] >= start) & (truth[:, 0] <= end)]


def configurations_along_path(rec: TestbedRecord, master: str = "robot",
                              window: Window = None) -> List[str]:
    """The configuration at each truth sample of the mission (truth_in_window's rows)."""
    return [configuration_of(mapping_at(rec, t), master)
            for t in truth_in_window(rec, window)[:, 0]]


def bandwidth_at_times(bandwidth: Sequence[Tuple[float, float]],
                       times: np.ndarray) -> np.ndarray:
    """The recorded bandwidth in force at each time (the last sample at or before it; before
    the first sample, the first one)."""
    if not bandwidth:
        return np.zeros(len(times))
    t, mbps = (np.asarray(c, dtype=float) for c in zip(*bandwidth))
    index = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 1)
    return mbps[index]


def driving_speed(steps: np.ndarray, dt: np.ndarray, where: np.ndarray, default: float) -> float:
    """Mean speed over the steps `where` (distance / time); `default` below MIN_DRIVEN_M."""
    length = float(steps[where].sum())
    return length / float(dt[where].sum()) if length >= MIN_DRIVEN_M else default


@dataclass(frozen=True)
class PathSteps:
    """The mission's ground truth as steps between samples, with what held at each start."""
    t: np.ndarray               # start of each step
    dt: np.ndarray
    length: np.ndarray
    mbps: np.ndarray            # the modelled link's bandwidth
    carried: np.ndarray         # the link carried AMCL's traffic
    out: np.ndarray             # AMCL ran off the robot
    driving: np.ndarray         # faster than MIN_DRIVING_MPS
    home_mps: float
    out_mps: float

    def saved_by_moving_out(self) -> np.ndarray:
        """Per step, the seconds the bound saves there: a driving step with AMCL home where the
        link carried it, at the speed with AMCL out."""
        saved = np.zeros(len(self.dt))
        home_but_carried = self.driving & self.carried & ~self.out
        saved[home_but_carried] = self.dt[home_but_carried] - \
            self.length[home_but_carried] / self.out_mps
        return saved


def path_steps(rec: TestbedRecord, amcl_mbps: float, master: str = "robot",
               window: Window = None) -> Optional[PathSteps]:
    """None where the record has no path or no bandwidth."""
    truth = truth_in_window(rec, window)
    if len(truth) < 2 or not rec.bandwidth:
        return None
    dt = np.diff(truth[:, 0])
    length = np.hypot(np.diff(truth[:, 1]), np.diff(truth[:, 2]))
    mbps = bandwidth_at_times(rec.bandwidth, truth[:-1, 0])
    out = np.array([c in AMCL_OUT for c in configurations_along_path(rec, master, window)[:-1]])
    driving = length > MIN_DRIVING_MPS * dt
    return PathSteps(truth[:-1, 0], dt, length, mbps, mbps >= amcl_mbps, out, driving,
                     driving_speed(length, dt, driving & ~out, SLOW_MPS),
                     driving_speed(length, dt, driving & out, FAST_MPS))
