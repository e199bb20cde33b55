"""The paper's evaluation figures of one test-bed run, read from its record (pure, no ROS): time
to complete, mean |omega|, markers, AMCL's error, share of time in each of Fig. 5's four
configurations, and the coverage bound (the time the best possible allocator could reach on
the coverage this run met). evaluation_table.py lays them out against the baseline and the
paper; evaluation_plots.py draws Fig. 5 and Fig. 6 from them.

The coverage bound, exactly: along the run's own ground-truth path between navigation's first
status and "done", each step between two truth samples (0.1 s apart) is driven at
FAST_MPS if the modelled bandwidth recorded at the step's start carries AMCL's traffic when it
runs apart from the robot (its input and output connections' bandwidth in the system model,
Characterisation.bandwidth_of_node: 0.2 + 0.02 Mbit/s on the test bed), else at SLOW_MPS.
Its time is the sum of length / speed; its gain is 1 - that time / (the same path's length /
SLOW_MPS), i.e. the share of the path with such coverage times (1 - SLOW_MPS / FAST_MPS).
Turns and stops at the goals cost every allocator alike, so the gain is taken over driving
alone; as a time to complete, evaluation_table applies it to the measured baseline. The
recorded bandwidth is a function of the place (coverage, shadowing along the path) and of
the time (interference episodes): the bound keeps each episode where this run met it.
"""
from dataclasses import dataclass, field
import math
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from anyscale_nav_demo.results import (AMCL_ON_LAPTOP, AR_ON_LAPTOP,  # noqa: F401 (re-export)
                                       BOTH_ON_LAPTOP, BOTH_ON_ROBOT, CONFIGURATION_COLOURS,
                                       CONFIGURATIONS, configuration_of,
                                       mean_abs_angular_velocity_deg)

from .testbed_record import TestbedRecord, mapping_at, pose_errors
from .tolerance_report import RunRow, path_time, run_row

# The safe-speed rule (anyscale_nav_demo/safe_speed.py: 0.1 m between corrections): AMCL at
# its optimal 5 Hz on the laptop allows 0.5 m/s, capped at the robot's 0.4 m/s; at its
# minimum 2 Hz on the robot, 0.2 m/s (the paper's two speeds).
FAST_MPS = 0.4
SLOW_MPS = 0.2


def path_window(rec: TestbedRecord) -> Tuple[float, float]:
    """(start, end) of the mission: navigation's first status to its "done", or to the record's
    last truth sample when the loop was not completed (or no status came)."""
    end = rec.truth[-1][0] if rec.truth else (rec.finished_t or 0.0)
    if not rec.navigation_status:
        return (rec.truth[0][0] if rec.truth else 0.0), end
    start = rec.navigation_status[0][0]
    duration = path_time(rec)
    return start, (start + duration if math.isfinite(duration) else end)


def truth_in_window(rec: TestbedRecord) -> np.ndarray:
    """(N, 3) t, x, y of the ground truth within the mission."""
    start, end = path_window(rec)
    truth = np.asarray(rec.truth, dtype=float).reshape(-1, 3)
    return truth[(truth[:, 0] >= start) & (truth[:, 0] <= end)]


def configurations_along_path(rec: TestbedRecord, master: str = "robot") -> List[str]:
    """The configuration at each truth sample of the mission (truth_in_window's rows)."""
    return [configuration_of(mapping_at(rec, t), master) for t in truth_in_window(rec)[:, 0]]


def configuration_shares(rec: TestbedRecord, master: str = "robot") -> Dict[str, float]:
    """Share (0..1) of the mission's time in each configuration, from the mapping changes."""
    start, end = path_window(rec)
    shares = {c: 0.0 for c in CONFIGURATIONS}
    if not end > start:
        return shares
    changes = [t for t, _, _, _ in rec.mappings if start < t < end]
    points = [start] + changes + [end]
    for a, b in zip(points, points[1:]):
        shares[configuration_of(mapping_at(rec, a), master)] += (b - a) / (end - start)
    return shares


def bandwidth_at_times(bandwidth: Sequence[Tuple[float, float]],
                       times: np.ndarray) -> np.ndarray:
    """The recorded bandwidth in force at each time (the last sample at or before it; before
    the first sample, the first one)."""
    if not bandwidth:
        return np.zeros(len(times))
    t, mbps = (np.asarray(c, dtype=float) for c in zip(*bandwidth))
    index = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 1)
    return mbps[index]


@dataclass(frozen=True)
class CoverageBound:
    path_m: float               # the mission's length along the ground truth
    carried_share: float        # share of that length where the link carried AMCL's traffic
    drive_s: float              # the path driven at FAST_MPS there, SLOW_MPS elsewhere
    gain: float                 # 1 - drive_s / (path_m / SLOW_MPS)


def coverage_bound(rec: TestbedRecord, amcl_mbps: float) -> CoverageBound:
    """See the module docstring. NaN figures where the record has no path or no bandwidth."""
    truth = truth_in_window(rec)
    if len(truth) < 2 or not rec.bandwidth:
        return CoverageBound(math.nan, math.nan, math.nan, math.nan)
    steps = np.hypot(np.diff(truth[:, 1]), np.diff(truth[:, 2]))
    carried = bandwidth_at_times(rec.bandwidth, truth[:-1, 0]) >= amcl_mbps
    length = float(steps.sum())
    if not length > 0:
        return CoverageBound(0.0, math.nan, 0.0, math.nan)
    drive = float(np.sum(np.where(carried, steps / FAST_MPS, steps / SLOW_MPS)))
    return CoverageBound(length, float(steps[carried].sum() / length), drive,
                         1.0 - drive / (length / SLOW_MPS))


def mean_abs_omega_deg_s(rec: TestbedRecord) -> float:
    """Mean |yaw rate| of the ground truth over the mission (the paper's Fig. 6 line); NaN if
    the record has no heading (recorded before truth_yaw was kept)."""
    start, end = path_window(rec)
    yaw = [(t, a) for t, a in rec.truth_yaw if start <= t <= end]
    if len(yaw) < 2:
        return math.nan
    t, a = zip(*yaw)
    return mean_abs_angular_velocity_deg(t, a)


@dataclass
class RunFigures:
    name: str                       # e.g. "baseline", "AnyScale seed 1"
    kind: str                       # baseline, paper, paper_local, optimal, best_case
    seed: int
    row: RunRow                     # path time, migrations, silences, violations
    mean_omega_deg_s: float = math.nan
    markers: int = 0
    rms_error_m: float = math.nan
    shares: Dict[str, float] = field(default_factory=dict)
    bound: CoverageBound = CoverageBound(math.nan, math.nan, math.nan, math.nan)


def run_figures(name: str, kind: str, seed: int, exit_code: int,
                rec: Optional[TestbedRecord], amcl_mbps: float,
                master: str = "robot") -> RunFigures:
    """A run's figures; without a record only its exit code and a note."""
    figures = RunFigures(name, kind, seed, run_row(0, 0, exit_code, rec))
    if rec is None:
        return figures
    figures.mean_omega_deg_s = mean_abs_omega_deg_s(rec)
    figures.markers = len(rec.markers_seen)
    errors = pose_errors(rec.truth, rec.estimate)
    figures.rms_error_m = float(np.sqrt(np.mean(errors ** 2))) if errors.size else math.nan
    figures.shares = configuration_shares(rec, master)
    figures.bound = coverage_bound(rec, amcl_mbps)
    return figures
