"""The link ahead on the planned path (no ROS): where the robot is on the planner's path, how
fast it goes, and what the link map (link_map.py) says of each remote scale's link over the
next horizon_s seconds at that speed. A fall in the cell the robot is in is the live
measurement's to judge, never the map's; but neither that cell nor any other counts as carrying
a node where the map knows it as a hole, nor where the map does not know it."""
from collections import deque
from dataclasses import dataclass
import math
from typing import Deque, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from .link_map import CellStats, LinkMap, LinkMapParams
from .param_spec import declared

# A robot slower than this stands: the cell it is in holds for the whole horizon.
STOPPED_MPS = 0.05
# Two poses further apart than this speed allows are a jump (a relocalisation), not a drive.
JUMP_MPS = 3.0


@dataclass(frozen=True)
class LinkForecastParams:
    """Every parameter of the link map and the forecast (the decision node's ~link_* ones),
    each declared once (param_spec)."""
    enabled: bool = declared(True, "anticipate the link along the planned path (false: the "
                             "reactive rules only)", name="link_forecast")
    horizon_s: float = declared(20.0, "how far ahead the forecast looks", "s",
                                name="link_forecast_horizon_s", minimum=1.0)
    move_cost_s: float = declared(
        3.0, "a move out, from the decision to the first output there", "s",
        name="link_forecast_move_cost_s", minimum=0.0)
    node_move_cost_s: Mapping[str, float] = declared(
        {}, "a node's own move cost, in place of ~link_forecast_move_cost_s", "node: s",
        name="node_link_forecast_move_cost_s")
    home_lead_s: float = declared(
        3.0, "a start at home to its first output, plus a margin: how early a node comes home",
        "s", name="link_forecast_home_lead_s", minimum=0.0)
    node_home_lead_s: Mapping[str, float] = declared(
        {}, "a node's own home lead, in place of ~link_forecast_home_lead_s", "node: s",
        name="node_link_forecast_home_lead_s")
    max_offset_m: float = declared(1.5, "a robot further off its path has no forecast", "m",
                                   name="link_forecast_max_offset_m", minimum=0.01)
    speed_window_s: float = declared(2.0, "the robot's speed: distance over this long a track",
                                     "s", name="link_forecast_speed_window_s", minimum=0.1)
    cruise_window_s: float = declared(
        15.0, "the forecast drives at the robot's top speed over this long: a stop at a goal "
        "does not blind it", "s", name="link_forecast_cruise_window_s", minimum=0.1)
    map: LinkMapParams = LinkMapParams()
    map_file: str = declared("", "the link map's file: loaded at start, saved every period "
                             "(empty: in memory only)", "path", name="link_map_file",
                             kind="text")
    save_period_s: float = declared(60.0, "how often the link map is saved", "s",
                                    name="link_map_save_period_s", minimum=1.0)
    path_topic: str = declared("", "the planner's nav_msgs/Path (empty: no path, no forecast)",
                               kind="text")
    pose_topic: str = declared("", "the robot's pose (PoseStamped, PoseWithCovarianceStamped "
                               "or Odometry; empty: tf ~map_frame -> ~base_frame)", kind="text")
    map_frame: str = declared("map", "the frame of the path and the link map", kind="frame")
    base_frame: str = declared("base_link", "the robot's base frame (tf pose)", kind="frame")

    def move_cost(self, node: str) -> float:
        return self.node_move_cost_s.get(node, self.move_cost_s)

    def home_lead(self, node: str) -> float:
        return self.node_home_lead_s.get(node, self.home_lead_s)


class PoseTrack:
    """The robot's recent poses (t, x, y): its speed, and where it was at a moment."""

    def __init__(self, window_s: float = 2.0, cruise_s: float = 15.0, keep_s: float = 10.0):
        self.window_s = window_s
        self.cruise_s = cruise_s
        self.keep_s = max(keep_s, window_s + cruise_s)
        self._poses: Deque[Tuple[float, float, float]] = deque()

    def add(self, t: float, x: float, y: float):
        """A pose; one that jumps further than JUMP_MPS allows starts the track anew."""
        if self._poses:
            t0, x0, y0 = self._poses[-1]
            if t < t0:
                return                          # older than the latest: already past
            if math.hypot(x - x0, y - y0) > JUMP_MPS * max(t - t0, 0.1):
                self._poses.clear()
        self._poses.append((t, x, y))
        while self._poses and self._poses[0][0] < t - self.keep_s:
            self._poses.popleft()

    def latest(self) -> Optional[Tuple[float, float, float]]:
        return self._poses[-1] if self._poses else None

    def at(self, t: float, within_s: float = 0.5) -> Optional[Tuple[float, float]]:
        """(x, y) at time t, interpolated; None if no pose is within `within_s` of it."""
        if not self._poses:
            return None
        times = [p[0] for p in self._poses]
        if t < times[0] - within_s or t > times[-1] + within_s:
            return None
        if t <= times[0]:
            return self._poses[0][1:]
        if t >= times[-1]:
            return self._poses[-1][1:]
        k = int(np.searchsorted(times, t))
        (ta, xa, ya), (tb, xb, yb) = self._poses[k - 1], self._poses[k]
        if tb - ta > 2 * within_s:
            return None                         # a gap in the track: no pose there
        w = (t - ta) / (tb - ta) if tb > ta else 1.0
        return xa + w * (xb - xa), ya + w * (yb - ya)

    def speed(self) -> float:
        """Distance over time along the last window_s of poses (0 with fewer than two)."""
        if len(self._poses) < 2:
            return 0.0
        end = self._poses[-1][0]
        recent = [p for p in self._poses if p[0] >= end - self.window_s]
        if len(recent) < 2 or recent[-1][0] - recent[0][0] <= 0:
            return 0.0
        xy = np.array([p[1:] for p in recent])
        return float(np.hypot(*np.diff(xy, axis=0).T).sum() / (recent[-1][0] - recent[0][0]))

    def cruise_speed(self) -> float:
        """The highest speed() over the last cruise_s: the speed to look ahead at. A robot that
        stopped at a goal, or is pulling away from one, drives on at about its cruise speed,
        and a speed too high is the safe side in both directions: a hole is foreseen sooner
        and a link ahead carries for less time."""
        if len(self._poses) < 2:
            return 0.0
        t = np.array([p[0] for p in self._poses])
        xy = np.array([p[1:] for p in self._poses])
        travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        ends = np.flatnonzero(t >= t[-1] - self.cruise_s)
        starts = np.searchsorted(t, t[ends] - self.window_s)
        span = t[ends] - t[starts]
        ok = span >= self.window_s / 2          # a window of a few poses is noise, not speed
        if not ok.any():
            return self.speed()
        return float(np.max((travelled[ends] - travelled[starts])[ok] / span[ok]))


class PathTracker:
    """The planned path (map frame) and the robot's place on it. The place is searched near the
    last one, so a path that passes itself does not make the robot jump along it; a pose that
    jumps, or a new path, is searched along the whole path."""

    def __init__(self, max_offset_m: float = 1.5, jump_m: float = 2.0):
        self.max_offset_m = max_offset_m
        self.jump_m = jump_m
        self._xy = np.zeros((0, 2))
        self._s = np.zeros(0)                  # arc length at each point
        self._last: Optional[Tuple[float, float, float]] = None   # x, y, arc length

    def set_path(self, points: Sequence[Tuple[float, float]]):
        """A new plan replaces the old one; an empty one means no plan."""
        xy = np.asarray(points, dtype=float).reshape(-1, 2)
        self._xy = xy
        self._s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]) \
            if len(xy) else np.zeros(0)
        self._last = None

    @property
    def has_path(self) -> bool:
        return len(self._xy) > 0

    @property
    def length_m(self) -> float:
        return float(self._s[-1]) if len(self._s) else 0.0

    def project(self, x: float, y: float) -> Optional[float]:
        """The arc length of the robot's place on the path; None without a path or with the
        robot further than max_offset_m from it."""
        if not self.has_path:
            return None
        if len(self._xy) == 1:
            best_s, dist = 0.0, math.hypot(x - self._xy[0, 0], y - self._xy[0, 1])
        else:
            local = self._last is not None and \
                math.hypot(x - self._last[0], y - self._last[1]) <= self.jump_m
            best_s, dist = self._nearest(x, y, self._window() if local else None)
            if local and dist > self.max_offset_m:
                best_s, dist = self._nearest(x, y, None)
        if dist > self.max_offset_m:
            self._last = None
            return None
        self._last = (x, y, best_s)
        return best_s

    def _window(self) -> slice:
        """The segments within jump_m behind the last place and 4 x jump_m ahead of it."""
        s = self._last[2]
        lo = max(int(np.searchsorted(self._s, s - self.jump_m)) - 1, 0)
        hi = min(int(np.searchsorted(self._s, s + 4 * self.jump_m)) + 1, len(self._xy) - 1)
        return slice(lo, max(hi, lo + 1))

    def _nearest(self, x: float, y: float, window: Optional[slice]) -> Tuple[float, float]:
        a, b = self._xy[:-1], self._xy[1:]
        s0 = self._s[:-1]
        if window is not None:
            a, b, s0 = a[window], b[window], s0[window]
        ab = b - a
        length2 = np.maximum((ab ** 2).sum(axis=1), 1e-12)
        w = np.clip(((np.array([x, y]) - a) * ab).sum(axis=1) / length2, 0.0, 1.0)
        near = a + w[:, None] * ab
        d = np.hypot(near[:, 0] - x, near[:, 1] - y)
        k = int(np.argmin(d))
        return float(s0[k] + w[k] * math.sqrt(length2[k])), float(d[k])

    def points_at(self, s: np.ndarray) -> np.ndarray:
        """(len(s), 2) places at arc lengths s, held at the path's end beyond it (np.interp
        holds its end values)."""
        return np.column_stack([np.interp(s, self._s, self._xy[:, 0]),
                                np.interp(s, self._s, self._xy[:, 1])])


@dataclass(frozen=True)
class Stretch:
    """A stretch of the horizon spent in one cell: from start_s to end_s from now."""
    start_s: float
    end_s: float
    stats: Optional[CellStats]          # None: unknown
    current: bool = False               # the cell the robot is in: judged by the measurement
    beside_hole: bool = False           # a hole within the map's hole_margin_cells


@dataclass(frozen=True)
class LinkForecast:
    """One remote scale's link over the next horizon_s, stretch by stretch. A known cell whose
    link was lost in more than hole_lost_fraction of its observations is a hole."""
    scale: str
    horizon_s: float
    stretches: Tuple[Stretch, ...]
    speed_mps: float
    hole_lost_fraction: float = 0.0

    def _hole(self, stats: CellStats) -> bool:
        return stats.lost_fraction > self.hole_lost_fraction

    def carries_for_s(self, need_mbps: float, live_mbps: float) -> float:
        """How long from now the link will carry need_mbps: in the current cell by the measured
        live_mbps (NaN or 0: not measured, or lost), then by the map's figure in each cell
        ahead. A hole does not carry, the current cell neither: what this answers lets a node
        skip the reactive rules, so the cell that just lost the link (at a coverage edge that
        flickers) does not count as carrying because the link came back for a moment, nor does
        a cell within the map's hole_margin_cells of a hole, where the edge flickers from lap to
        lap (docs/design/decision_node.md). An unknown cell does not carry, the current one
        neither: an empty map carries nothing. horizon_s if it carries throughout."""
        for st in self.stretches:
            ok = st.stats is not None and not self._hole(st.stats) and not st.beside_hole and (
                live_mbps >= need_mbps if st.current else st.stats.low_mbps >= need_mbps)
            if not ok:
                return st.start_s
        return self.horizon_s

    def falls_below(self, need_mbps: float) -> Optional[Tuple[float, float]]:
        """(seconds from now, Mbit/s there) of the first known cell ahead whose figure is below
        need_mbps or that is a hole; None if none is foreseen. The current cell never counts
        (the measurement judges it), nor does an unknown one."""
        for st in self.stretches:
            if st.current or st.stats is None:
                continue
            if st.stats.low_mbps < need_mbps or self._hole(st.stats):
                return st.start_s, 0.0 if self._hole(st.stats) else st.stats.low_mbps
        return None

    def describe(self, live_mbps: float) -> str:
        """One line for a person, e.g. '24 Mbit/s for 12 s, then 0 Mbit/s (lost 80 %) from
        12 s, unknown from 16 s'."""
        parts: List[Tuple[str, float]] = []
        for st in self.stretches:
            if st.current:
                word = "now unmeasured" if not math.isfinite(live_mbps) else \
                    f"{live_mbps:.0f} Mbit/s"
            elif st.stats is None:
                word = "unknown"
            else:
                word = f"{st.stats.low_mbps:.0f} Mbit/s" + (
                    f" (lost {100 * st.stats.lost_fraction:.0f} %)" if st.stats.lost_fraction
                    else "")
            if not parts or parts[-1][0] != word:
                parts.append((word, st.start_s))
        if not parts:
            return "no forecast"
        text = [f"{parts[0][0]}" + (f" for {parts[1][1]:.0f} s" if len(parts) > 1 else
                                    f" for {self.horizon_s:.0f} s (the horizon)")]
        text += [f"{word} from {start:.0f} s" for word, start in parts[1:]]
        speed = "standing" if self.speed_mps < STOPPED_MPS else f"at {self.speed_mps:.2f} m/s"
        return ", then ".join(text) + f" ({speed})"


def forecast_links(link_map: LinkMap, scales: Sequence[str], path: PathTracker,
                   x: float, y: float, speed_mps: float,
                   horizon_s: float) -> Optional[Dict[str, LinkForecast]]:
    """Per remote scale, the link over the next horizon_s for a robot at (x, y) driving along
    `path` at speed_mps (standing: its current cell throughout; past the path's end: its end
    cell). None when the robot is not on the path (or there is none)."""
    s = path.project(x, y)
    if s is None:
        return None
    if speed_mps < STOPPED_MPS:
        cells, starts = [link_map.cell_of(x, y)], np.zeros(1)
    else:
        r = link_map.params.resolution_m
        distance = np.arange(0.0, speed_mps * horizon_s, r / 10.0)
        ij = np.floor(path.points_at(s + distance) / r).astype(int)
        change = np.flatnonzero(np.any(ij[1:] != ij[:-1], axis=1)) + 1
        cells = [tuple(c) for c in ij[np.concatenate([[0], change])]]
        starts = np.concatenate([[0.0], _boundaries(path, s, distance, ij, change, r)])
        starts /= speed_mps
    ends = np.append(starts[1:], horizon_s)
    out = {}
    for scale in scales:
        out[scale] = LinkForecast(scale, horizon_s, tuple(
            Stretch(float(a), float(b), link_map.stats(scale, c), k == 0,
                    link_map.beside_hole(scale, c))
            for k, (c, a, b) in enumerate(zip(cells, starts, ends))), speed_mps,
            link_map.params.hole_lost_fraction)
    return out


def _boundaries(path: PathTracker, s: float, distance: np.ndarray, ij: np.ndarray,
                change: np.ndarray, r: float) -> np.ndarray:
    """Where the path leaves each cell, to r/640 (1.6 mm in 1 m cells): bisection between the
    samples around each change (a sample every r/10 would put a hole up to r/10 later than it
    is)."""
    lo, hi = distance[change - 1], distance[change]
    before = ij[change - 1]
    for _ in range(6):
        mid = (lo + hi) / 2
        inside = np.all(np.floor(path.points_at(s + mid) / r).astype(int) == before, axis=1)
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    return hi
