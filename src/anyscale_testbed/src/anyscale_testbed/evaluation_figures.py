"""The paper's evaluation figures of one test-bed run, read from its record (pure, no ROS): time
to complete, mean |omega|, markers, AMCL's error, share of time in each of Fig. 5's four
configurations, AMCL's rate and the robot's cruise speed with every node home (the premise,
premise_figures.py), and the coverage bound (the time the best possible allocator could reach on
the coverage this run met). evaluation_table.py lays them out against the baseline and the
paper; evaluation_plots.py draws Fig. 5 and Fig. 6 from them.

The coverage bound, exactly: the time this run would have taken had AMCL been on the laptop
wherever the link carried its traffic, and on the robot elsewhere, at the speeds this run's
robot drove in each case. Along the run's own ground-truth path between navigation's first
status and "done", a step between two truth samples (0.1 s apart) counts as driving above
MIN_DRIVING_MPS; the run's driving speed with AMCL on the robot and with AMCL out are each
measured over its driving steps (the premise's SLOW_MPS and FAST_MPS for a case it drove less
than MIN_DRIVEN_M in). A driving step where the modelled bandwidth recorded at its start
carries AMCL's traffic when it runs apart from the robot (its input and output connections'
bandwidth in the system model, Characterisation.bandwidth_of_node: 0.2 + 0.02 Mbit/s on the
test bed) but where AMCL was home takes its length at the speed with AMCL out; one where the
link does not carry it but AMCL was out takes its length at the speed with AMCL home; every
other step, and every turn and stop, takes what it took. Measured speeds, not the premise's
0.2 and 0.4 m/s: the starved robot's speed varies from run to run (0.19-0.28 m/s with every
node home), and a bound at the premise's speeds was beaten by runs that drove faster at home
than the baseline did (102 % of its gain). The recorded bandwidth is a function of the place
(coverage, shadowing along the path) and of the time (interference episodes): the bound keeps
each episode where this run met it. evaluation_table states its gain against the baseline;
evaluation_shortfall.py splits what a test left of it by cause.

The share of the bound's gain at the run's own speeds (own_speed_share) needs no baseline: the
same steps with AMCL home throughout (every driving step with AMCL out at the speed with AMCL
home) give the time the run would have taken without a move, and the share is what the run
saved against that over what the bound saves. A baseline run is another run, on a shared host
whose speed drifts within the hour (AMCL 1.86 Hz at home in one baseline, 1.33 Hz in the test
after it): a share against it reads that drift as well as the allocator.
"""
from dataclasses import dataclass, field
import math
from typing import Dict, List, Optional, Tuple

import numpy as np

from anyscale_nav_demo.results import (AMCL_ON_LAPTOP, AR_ON_LAPTOP,  # noqa: F401 (re-export)
                                       BOTH_ON_LAPTOP, BOTH_ON_ROBOT, CONFIGURATION_COLOURS,
                                       CONFIGURATIONS, configuration_of,
                                       mean_abs_angular_velocity_deg)

from .evaluation_shortfall import NO_SHORTFALL, Shortfall, shortfall
from .path_steps import Window, path_steps, path_window, truth_in_window
from .premise_figures import figures_with_every_node_home
from .testbed_figures import pose_errors
from .testbed_record import MOVE_OUT, TestbedRecord, kind_of_move, mapping_at
from .tolerance_report import RunRow, path_time, run_row


def returns_along_path(rec: TestbedRecord) -> List[Tuple[float, float, str]]:
    """(x, y, kind) where the robot was (ground truth) when each return of the mission was
    decided (testbed_record.kind_of_move): Fig. 5 marks them."""
    truth = truth_in_window(rec)
    if len(truth) < 2:
        return []
    found = []
    for e in rec.events:
        kind = kind_of_move(e)
        if kind and kind != MOVE_OUT and truth[0, 0] <= e.decided_t <= truth[-1, 0]:
            found.append((float(np.interp(e.decided_t, truth[:, 0], truth[:, 1])),
                          float(np.interp(e.decided_t, truth[:, 0], truth[:, 2])), kind))
    return found


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


@dataclass(frozen=True)
class CoverageBound:
    path_m: float               # the mission's length along the ground truth
    carried_share: float        # share of that length where the link carried AMCL's traffic
    home_mps: float             # driving speed with AMCL on the robot (measured, or SLOW_MPS)
    out_mps: float              # driving speed with AMCL out (measured, or FAST_MPS)
    time_s: float               # the time to complete with AMCL out wherever the link carried it
    taken_s: float              # the time the run took
    home_time_s: float          # the time to complete with AMCL home throughout


NO_BOUND = CoverageBound(math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan)


def own_speed_share(bound: CoverageBound) -> float:
    """The share of the bound's gain the run reached, at its own speeds (see the module
    docstring); NaN where the bound has nothing to gain or a figure is missing."""
    reachable = bound.home_time_s - bound.time_s
    if not (math.isfinite(reachable) and reachable > 0 and math.isfinite(bound.taken_s)):
        return math.nan
    return (bound.home_time_s - bound.taken_s) / reachable


def coverage_bound(rec: TestbedRecord, amcl_mbps: float, master: str = "robot",
                   window: Window = None) -> CoverageBound:
    """See the module docstring. NaN figures where the record has no path or no bandwidth, and
    no time where the loop was not completed. `window`: (start, end) of a part of the mission
    (a lap) in place of the whole; its time is end - start."""
    steps = path_steps(rec, amcl_mbps, master, window)
    if steps is None:
        return NO_BOUND
    taken = path_time(rec) if window is None else window[1] - window[0]
    total = float(steps.length.sum())
    if not total > 0:
        return CoverageBound(0.0, math.nan, math.nan, math.nan, taken, taken, taken)

    def at_home_speed(where):
        return float(np.sum(steps.length[where] / steps.home_mps - steps.dt[where]))
    lost = at_home_speed(steps.driving & ~steps.carried & steps.out)
    return CoverageBound(total, float(steps.length[steps.carried].sum() / total),
                         steps.home_mps, steps.out_mps,
                         taken - float(steps.saved_by_moving_out().sum()) + lost, taken,
                         taken + at_home_speed(steps.driving & steps.out))


def mean_abs_omega_deg_s(rec: TestbedRecord) -> float:
    """Mean |yaw rate| of the ground truth over the mission (the paper's Fig. 6 line); NaN if
    the record has no heading (recorded before truth_yaw was kept)."""
    start, end = path_window(rec)
    yaw = [(t, a) for t, a in rec.truth_yaw if start <= t <= end]
    if len(yaw) < 2:
        return math.nan
    t, a = zip(*yaw)
    return mean_abs_angular_velocity_deg(t, a)


def turning_per_metre_deg(rec: TestbedRecord) -> float:
    """Heading change per metre driven over the mission (deg/m): how much the robot turns for
    the path it covers. Mean |omega| is this times the mean speed, so on the same loop a robot
    that drives faster turns faster at the same corners; this figure tells whether it also
    weaves more. NaN without heading or path."""
    start, end = path_window(rec)
    yaw = [(t, a) for t, a in rec.truth_yaw if start <= t <= end]
    truth = truth_in_window(rec)
    length = float(np.hypot(np.diff(truth[:, 1]), np.diff(truth[:, 2])).sum()) \
        if len(truth) >= 2 else 0.0
    if len(yaw) < 2 or not length > 0:
        return math.nan
    t, a = zip(*yaw)
    return mean_abs_angular_velocity_deg(t, a) * (t[-1] - t[0]) / length


@dataclass
class RunFigures:
    name: str                       # e.g. "baseline", "AnyScale seed 1"
    kind: str                       # baseline, paper, paper_local, optimal, best_case
    seed: int
    row: RunRow                     # path time, migrations, silences, violations
    # The seed of the interleaved pair (a baseline, then its test) this run belongs to; 0: none.
    pair: int = 0
    mean_omega_deg_s: float = math.nan
    turning_deg_per_m: float = math.nan
    markers: int = 0
    rms_error_m: float = math.nan
    shares: Dict[str, float] = field(default_factory=dict)
    bound: CoverageBound = NO_BOUND
    shortfall: Shortfall = NO_SHORTFALL     # what an AnyScale test left of the bound
    amcl_hz_home: float = math.nan          # with every node on the robot (the premise)
    cruise_mps_home: float = math.nan
    # evaluation_laps.LapFigures per lap of a run that drove its loop more than once
    laps: list = field(default_factory=list)


def run_figures(name: str, kind: str, seed: int, exit_code: int,
                rec: Optional[TestbedRecord], amcl_mbps: float,
                master: str = "robot", pair: int = 0) -> RunFigures:
    """A run's figures; without a record only its exit code and a note."""
    figures = RunFigures(name, kind, seed, run_row(0, 0, exit_code, rec), pair)
    if rec is None:
        return figures
    figures.mean_omega_deg_s = mean_abs_omega_deg_s(rec)
    figures.turning_deg_per_m = turning_per_metre_deg(rec)
    figures.markers = len(rec.markers_seen)
    errors = pose_errors(rec.truth, rec.estimate)
    figures.rms_error_m = float(np.sqrt(np.mean(errors ** 2))) if errors.size else math.nan
    figures.shares = configuration_shares(rec, master)
    figures.bound = coverage_bound(rec, amcl_mbps, master)
    home = figures_with_every_node_home(rec)
    if home is not None:
        figures.amcl_hz_home, figures.cruise_mps_home = home["amcl_hz"], home["cruise_speed"]
    steps = path_steps(rec, amcl_mbps, master)
    if steps is not None and kind not in ("baseline", "best_case"):
        figures.shortfall = shortfall(rec, steps)
    return figures
