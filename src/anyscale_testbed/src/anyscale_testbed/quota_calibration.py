"""The robot's CPU quota for the day (issue 13's premise): the quota at which AMCL, with every
node on the robot, runs at the premise's 2 Hz, found by short runs with the link down. Pure
(no ROS, no test bed): the runs are the caller's `measure`.

Why each evaluation calibrates: this shared VM's speed drifts, and with it AMCL's rate under a
fixed quota (every node home at 0.34 cores: 2.39 Hz one morning, 3.27 Hz two days later, 1.77-
3.18 Hz over a week), so a quota written into testbed_calibration.yaml holds the premise only on
the day it was measured. A baseline off the premise makes every gain meaningless.

Each step assumes AMCL's rate grows in proportion to the CPU left over by the robot's other
nodes, rate = k x (quota - PRIOR_OTHER_CORES) (three quotas measured on one day, 0.30-0.37
cores, lay on such a line), with k fitted by least squares to every measurement so far. Not the
secant through the last two: one 75 s measurement varies by about +-0.3 Hz, and on 2026-11-27
0.254 cores read 2.25 Hz and 0.239 cores 2.32 Hz, so the secant had no usable slope, and the
next reading (0.223 cores: 1.53 Hz) was as noisy again; the fit averages the noise out.

Why the quota is kept only where AMCL runs at least its 2 Hz, not 2 +- 0.2 Hz: the premise is a
robot that alone sustains its minimum rates, and no more. A quota kept at 1.8-1.9 Hz is a robot
that alone breaks its own minimum: with nothing moving, AMCL then fell silent for longer than
its Δ (tolerance bench 2026-11-27, run 4: 1.85 Hz at home, 4 silences of 2.09-2.20 s; in that
bench and the evaluations of 2026-11-26/27 no run at 1.99 Hz or more had one at home). The
window is 0.3 Hz wide (the old one 0.4), and the fit aims at its middle, 2.15 Hz.
"""
from dataclasses import dataclass
import math
from typing import Callable, List, Sequence, Tuple

from .premise_figures import PREMISE_AMCL_HZ

PRIOR_OTHER_CORES = 0.12      # the first step's guess of what the other nodes use (see above)
SETTLED_HZ = (PREMISE_AMCL_HZ, PREMISE_AMCL_HZ + 0.3)   # a quota whose AMCL rate is in here is kept
TARGET_HZ = sum(SETTLED_HZ) / 2                          # what each step aims at
QUOTA_BOUNDS = (0.15, 0.8)    # cores: below, the drivers miss their rates; above, no premise
MAX_RUNS = 3


class CalibrationError(RuntimeError):
    """A calibration run gave no AMCL rate (it failed, or AMCL never published)."""


@dataclass(frozen=True)
class QuotaPoint:
    quota: float        # cores
    amcl_hz: float      # AMCL's rate with every node home at that quota


def next_quota(points: Sequence[QuotaPoint], target_hz: float = TARGET_HZ) -> float:
    """The quota at which rate = k x (quota - PRIOR_OTHER_CORES), k fitted to `points` by least
    squares, gives target_hz; within QUOTA_BOUNDS."""
    spare = [p.quota - PRIOR_OTHER_CORES for p in points]
    k = (sum(x * p.amcl_hz for x, p in zip(spare, points))
         / max(sum(x * x for x in spare), 1e-9))
    quota = PRIOR_OTHER_CORES + target_hz / k if k > 0 else QUOTA_BOUNDS[1]
    return round(min(max(quota, QUOTA_BOUNDS[0]), QUOTA_BOUNDS[1]), 3)


def settled(point: QuotaPoint) -> bool:
    return SETTLED_HZ[0] <= point.amcl_hz <= SETTLED_HZ[1]


def calibrate_quota(start_quota: float, measure: Callable[[float], float],
                    log: Callable[[str], None] = print,
                    max_runs: int = MAX_RUNS) -> Tuple[float, List[QuotaPoint]]:
    """Measures AMCL's rate at start_quota, steps towards the premise until a measurement
    settles or max_runs were made; returns the quota to run at and the measurements. After
    max_runs without settling it is the last step's quota, not measured (said in the log); a
    step that stays at the bound just measured ends it there (the host too slow or too fast
    for the premise within QUOTA_BOUNDS, said in the log)."""
    quota, points = start_quota, []
    for k in range(1, max_runs + 1):
        hz = measure(quota)
        if not (math.isfinite(hz) and hz > 0):
            raise CalibrationError(f"calibration run {k} at {quota:g} cores gave no AMCL rate")
        points.append(QuotaPoint(quota, hz))
        if settled(points[-1]):
            log(f"calibration: robot {quota:g} cores, AMCL {hz:.2f} Hz at home: kept")
            return quota, points
        step = next_quota(points)
        if step == quota and quota in QUOTA_BOUNDS:
            # Clipped to the bound just measured: another run there would read the same.
            log(off_premise_at_bound(points[-1]))
            return quota, points
        log(f"calibration: robot {quota:g} cores, AMCL {hz:.2f} Hz at home "
            f"(premise {SETTLED_HZ[0]:g}-{SETTLED_HZ[1]:g} Hz): next {step:g} cores")
        quota = step
    log(f"calibration: not settled after {max_runs} runs; running at {quota:g} cores, "
        f"the last step, unmeasured")
    return quota, points


def off_premise_at_bound(point: QuotaPoint) -> str:
    """The line for a calibration that ends at one of QUOTA_BOUNDS off the premise."""
    slow = point.amcl_hz < SETTLED_HZ[0]
    return (f"calibration: robot {point.quota:g} cores, AMCL {point.amcl_hz:.2f} Hz at home, "
            f"{'below' if slow else 'above'} the premise's {SETTLED_HZ[0]:g}-{SETTLED_HZ[1]:g} "
            f"Hz at the quota's {'upper' if slow else 'lower'} bound: this host is too "
            f"{'slow' if slow else 'fast'} for the premise now; running at {point.quota:g} "
            f"cores, off the premise")
