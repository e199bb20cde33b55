"""The robot's path coloured by the active configuration (the paper's Fig. 5), pure Python.

A configuration is where the nodes run relative to the master scale ("all on robot",
"laptop: amcl, ar_recognition"). This module labels and names configurations, gives each a
stable colour, and accumulates the robot's path as (t, x, y) samples tagged with the
configuration, so that the rospy node (nodes/configuration_path) only has to turn segments
into rviz markers. It also keeps the distance and time spent per configuration, the table a
demo run prints at the end.
"""
import math
from collections import deque
from dataclasses import dataclass
from typing import Deque, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

# A configuration: the sorted (node, scale) pairs of the nodes NOT on the master scale. Pairs
# rather than bare node names: with more than two scales, amcl on "laptop" and amcl on "server"
# are different configurations. The empty tuple means everything runs on the master.
Configuration = Tuple[Tuple[str, str], ...]
ALL_ON_MASTER: Configuration = ()

RGBA = Tuple[float, float, float, float]
# The paper's Fig. 5 colours: red for everything on the robot, then green, blue, yellow for the
# configurations in the order they first appear, then more distinct colours for larger systems.
MASTER_COLOUR: RGBA = (0.85, 0.10, 0.10, 1.0)
PALETTE: Tuple[RGBA, ...] = (
    (0.10, 0.75, 0.20, 1.0),   # green
    (0.15, 0.35, 0.95, 1.0),   # blue
    (0.95, 0.85, 0.10, 1.0),   # yellow
    (0.80, 0.20, 0.85, 1.0),   # magenta
    (0.10, 0.80, 0.85, 1.0),   # cyan
    (1.00, 0.55, 0.05, 1.0),   # orange
    (0.55, 0.35, 0.20, 1.0),   # brown
    (0.60, 0.60, 0.60, 1.0),   # grey
)

DEFAULT_MIN_STEP_M = 0.05
DEFAULT_MAX_POINTS = 20000


def configuration_of(mapping: Mapping[str, str], master: str) -> Configuration:
    """The configuration of a mapping {node: scale}: its sorted off-master (node, scale) pairs."""
    return tuple(sorted((node, scale) for node, scale in mapping.items() if scale != master))


def configuration_name(config: Configuration, master: str) -> str:
    """A readable name: "all on robot", "laptop: amcl, ar_recognition", or, with several
    remote scales, "laptop: amcl; server: ar_recognition" (scales in name order)."""
    if not config:
        return f"all on {master}"
    by_scale: Dict[str, List[str]] = {}
    for node, scale in config:
        by_scale.setdefault(scale, []).append(node)
    return "; ".join(f"{scale}: {', '.join(sorted(nodes))}"
                     for scale, nodes in sorted(by_scale.items()))


class ConfigurationColours:
    """A colour per configuration: everything-on-master is always MASTER_COLOUR, the others take
    PALETTE in the order they first appear (so a run's colours do not depend on hashing or on
    configurations that never occur), cycling if there are more configurations than colours."""

    def __init__(self, master_colour: RGBA = MASTER_COLOUR, palette: Sequence[RGBA] = PALETTE):
        if not palette:
            raise ValueError("palette: needs at least one colour")
        self._master_colour = master_colour
        self._palette = tuple(palette)
        self._assigned: Dict[Configuration, RGBA] = {}

    def colour(self, config: Configuration) -> RGBA:
        if config == ALL_ON_MASTER:
            return self._master_colour
        if config not in self._assigned:
            self._assigned[config] = self._palette[len(self._assigned) % len(self._palette)]
        return self._assigned[config]


@dataclass(frozen=True)
class PathPoint:
    t: float
    x: float
    y: float
    config: Configuration


@dataclass(frozen=True)
class Segment:
    """A run of the path under one configuration, as (x, y) points in order."""
    config: Configuration
    points: Tuple[Tuple[float, float], ...]


@dataclass
class Totals:
    distance_m: float = 0.0
    time_s: float = 0.0


def split_segments(points: Iterable[PathPoint]) -> List[Segment]:
    """Runs of consecutive points with one configuration. Each run ends at the first point of the
    next run, so the drawn line has no gap at a change: the stretch driven up to the point where
    the change was seen is coloured with the configuration that was active while driving it."""
    segments: List[Segment] = []
    run: List[Tuple[float, float]] = []
    config: Optional[Configuration] = None
    for p in points:
        if config is not None and p.config != config:
            run.append((p.x, p.y))
            segments.append(Segment(config, tuple(run)))
            run = []
        config = p.config
        run.append((p.x, p.y))
    if run:
        segments.append(Segment(config, tuple(run)))
    return segments


def format_totals(totals: Mapping[Configuration, Totals], master: str) -> str:
    """The per-configuration table printed at the end of a demo run, in order of first use."""
    rows = [(configuration_name(c, master), t) for c, t in totals.items()]
    width = max([len("configuration")] + [len(name) for name, _ in rows])
    total_d = sum(t.distance_m for _, t in rows)
    total_t = sum(t.time_s for _, t in rows)
    lines = [f"{'configuration':<{width}}  {'distance':>10}  {'time':>9}  {'share':>6}"]
    for name, t in rows:
        share = 100.0 * t.time_s / total_t if total_t > 0 else 0.0
        lines.append(f"{name:<{width}}  {t.distance_m:>8.2f} m  {t.time_s:>7.1f} s  "
                     f"{share:>5.1f}%")
    lines.append(f"{'total':<{width}}  {total_d:>8.2f} m  {total_t:>7.1f} s")
    return "\n".join(lines)


class PathAccumulator:
    """The robot's path tagged with the configuration, decimated and bounded in memory.

    add() keeps a sample only when the robot moved at least min_step_m since the last kept one,
    or the configuration changed (so every change has its own boundary point). At most
    max_points are kept, the oldest dropped first: a long run must not grow the node's memory or
    the marker message without bound. Totals are cumulative over every sample and are not
    affected by decimation or by dropping old points.
    """

    def __init__(self, min_step_m: float = DEFAULT_MIN_STEP_M,
                 max_points: int = DEFAULT_MAX_POINTS):
        if not (math.isfinite(min_step_m) and min_step_m >= 0.0):
            raise ValueError(f"min_step_m: expected a finite number >= 0, got {min_step_m!r}")
        if int(max_points) != max_points or max_points < 2:
            raise ValueError(f"max_points: expected an integer >= 2, got {max_points!r}")
        self.min_step_m = float(min_step_m)
        self._points: Deque[PathPoint] = deque(maxlen=int(max_points))
        self._totals: Dict[Configuration, Totals] = {}
        self._last_sample: Optional[PathPoint] = None

    def add(self, t: float, x: float, y: float, config: Configuration) -> bool:
        """One pose sample at time t [s] under config; True if it was kept as a path point."""
        if not all(math.isfinite(v) for v in (t, x, y)):
            return False        # a broken transform must not poison the totals with NaN
        self._totals.setdefault(config, Totals())
        previous = self._last_sample
        if previous is not None:
            # Time between samples belongs to the configuration active at the earlier one;
            # a clock that went back (a restarted simulation) adds nothing rather than less.
            self._totals[previous.config].time_s += max(0.0, t - previous.t)
        self._last_sample = PathPoint(t, x, y, config)

        last = self._points[-1] if self._points else None
        if last is not None and last.config == config and \
                math.hypot(x - last.x, y - last.y) < self.min_step_m:
            return False
        if last is not None:
            # Distance along the kept path, counted like time: to the earlier point's config.
            self._totals[last.config].distance_m += math.hypot(x - last.x, y - last.y)
        self._points.append(PathPoint(t, x, y, config))
        return True

    @property
    def points(self) -> Tuple[PathPoint, ...]:
        return tuple(self._points)

    def segments(self) -> List[Segment]:
        return split_segments(self._points)

    def totals(self) -> Dict[Configuration, Totals]:
        """Distance [m] and time [s] per configuration, in order of first appearance."""
        return {c: Totals(t.distance_m, t.time_s) for c, t in self._totals.items()}

    def distance_m(self) -> float:
        return sum(t.distance_m for t in self._totals.values())
