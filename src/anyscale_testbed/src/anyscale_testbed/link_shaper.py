"""The WiFi link shaper's decisions, without ROS: what the test bed's robot-laptop link should
be (up at some rate, or down) for a bandwidth from the WiFi model, when to (re)apply it with
tc/ip, the coverage model from an OccupancyGrid's plain values, the coverage grid shown in
rviz, the schedule parameter, and the share of a path that has coverage.

The node (nodes/link_shaper) only reads parameters and messages and runs the argv lists built
here; everything that decides is here so that it can be tested without a ROS master or root.
"""
from dataclasses import dataclass, replace
import math
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from anyscale_core.param_spec import REQUIRED, Param, ParamError
from anyscale_nav_demo.occupancy_map import MapError, load_map
from anyscale_testbed.two_scale_testbed import (TwoScaleLayout, link_commands, run,
                                                shape_commands)
from anyscale_testbed.wifi_link_model import (CoverageModel, RadioParams, ScriptedSchedule,
                                              walls_crossed)

# The best usable rate of the model (54 Mbit/s PHY, half usable by TCP): 100 in the grid.
FULL_SCALE_MBPS = 27.0
# An OccupancyGrid value at or above this is a wall for the radio (as for the laser);
# unknown (-1) is open space, like outside the map.
OCCUPIED_THRESHOLD = 50


@dataclass(frozen=True)
class LinkSetting:
    """What the link should be: down, or up and shaped to `mbps`."""
    up: bool
    mbps: float = 0.0

    def describe(self) -> str:
        return f"{self.mbps:.1f} Mbit/s" if self.up else "link down"


def link_setting_for(mbps: float) -> LinkSetting:
    """The setting for a model bandwidth; 0 (no coverage) or less takes the link down.
    The rate is kept at tc's kbit resolution so that equal rates compare equal."""
    if not mbps > 0:          # also NaN: no usable number, no link
        return LinkSetting(False, 0.0)
    return LinkSetting(True, round(float(mbps), 3))


def setting_commands(layout: TwoScaleLayout, previous: Optional[LinkSetting],
                     new: LinkSetting, burst_kbit: int = 32) -> List[List[str]]:
    """The argv lists that take the link from `previous` (None = unknown) to `new`.

    Going down is only `ip link set down`: the qdisc stays, it does not matter on a down link.
    Coming up, the rate is set before the link goes up so no packet passes at the old rate.
    """
    if not new.up:
        return link_commands(layout, False)
    cmds = []
    if previous is None or not previous.up or previous.mbps != new.mbps:
        cmds += shape_commands(layout, new.mbps, burst_kbit)
    if previous is None or not previous.up:
        cmds += link_commands(layout, True)
    return cmds


def apply_setting(layout: TwoScaleLayout, previous: Optional[LinkSetting], new: LinkSetting,
                  burst_kbit: int = 32,
                  runner: Callable[[List[str]], object] = run) -> List[List[str]]:
    """Runs the commands for the change (root needed); returns them. A failing command raises
    two_scale_testbed.TwoScaleError naming it and what it printed; later ones are not run."""
    cmds = setting_commands(layout, previous, new, burst_kbit)
    for argv in cmds:
        runner(argv)
    return cmds


class SettingTracker:
    """Decides when a setting has to be (re)applied, so that tc runs only on a change.

    Every change is due at once, in particular losing coverage: the model says the link is
    gone now, and a delayed `down` would let traffic through that the radio would not carry.
    After a failed attempt the same setting is retried every `retry_s`, not on every tick,
    so a persistent tc error is not logged at the node's rate.
    """

    def __init__(self, retry_s: float = 5.0):
        self.retry_s = retry_s
        self.applied: Optional[LinkSetting] = None    # None: unknown (nothing applied yet)
        self._failed: Optional[Tuple[LinkSetting, float]] = None

    def due(self, wanted: LinkSetting, now: float) -> bool:
        if wanted == self.applied:
            return False
        if self._failed is not None and self._failed[0] == wanted:
            return now - self._failed[1] >= self.retry_s
        return True

    def succeeded(self, setting: LinkSetting):
        self.applied, self._failed = setting, None

    def failed(self, setting: LinkSetting, now: float):
        # A partly applied change leaves the link in an unknown state: redo all of it next time.
        self.applied, self._failed = None, (setting, now)


def coverage_model_from_grid(width: int, height: int, resolution: float, origin_x: float,
                             origin_y: float, data: Sequence[int],
                             access_point_xy: Tuple[float, float],
                             radio: RadioParams = RadioParams()) -> CoverageModel:
    """A CoverageModel from nav_msgs/OccupancyGrid values: data row-major, row 0 at origin y
    (the message's order), 100 occupied, 0 free, -1 unknown. The origin must be unrotated."""
    if width <= 0 or height <= 0:
        raise ValueError(f"grid size must be positive, got {width} x {height}")
    if not resolution > 0:
        raise ValueError(f"grid resolution must be > 0, got {resolution}")
    if len(data) != width * height:
        raise ValueError(f"grid data has {len(data)} cells, expected {width} x {height} = "
                         f"{width * height}")
    cells = np.asarray(data, dtype=np.int16).reshape(height, width)
    return CoverageModel(cells >= OCCUPIED_THRESHOLD, float(resolution),
                         (float(origin_x), float(origin_y)),
                         (float(access_point_xy[0]), float(access_point_xy[1])), radio)


def coverage_model_from_map_file(path: str, access_point_xy: Tuple[float, float],
                                 radio: RadioParams = RadioParams()) -> CoverageModel:
    """A CoverageModel from a map_server YAML (the floor plan the robot's map_server serves);
    ValueError names the file and what is wrong with it."""
    try:
        occ = load_map(path)
    except (MapError, OSError) as e:
        raise ValueError(str(e)) from None
    if abs(occ.origin[2]) > 1e-6:
        raise ValueError(f"{path}: origin is rotated (yaw {occ.origin[2]:.3f} rad); the coverage "
                         f"model needs an axis-aligned map")
    return coverage_model_from_grid(occ.width, occ.height, occ.resolution, occ.origin[0],
                                    occ.origin[1], occ.data.ravel(), access_point_xy, radio)


@dataclass(frozen=True)
class CoverageGrid:
    """Bandwidth (Mbit/s) at the centres of square cells of `resolution` m; row 0 at origin y."""
    mbps: np.ndarray                # (rows, cols)
    resolution: float
    origin_xy: Tuple[float, float]

    def occupancy_values(self, full_scale_mbps: float = FULL_SCALE_MBPS) -> List[int]:
        """Row-major OccupancyGrid data: bandwidth as 0..100 % of full scale (0 = no link)."""
        scaled = np.clip(np.round(self.mbps / full_scale_mbps * 100.0), 0, 100)
        return [int(v) for v in scaled.astype(np.int8).ravel()]


def coverage_grid(model: CoverageModel, step_m: float = 0.5) -> CoverageGrid:
    """The model's bandwidth over its map, every `step_m` (the map's cells are too fine to be
    worth a path-loss evaluation each, and rviz shows 0.5 m cells well enough)."""
    if not step_m > 0:
        raise ValueError(f"coverage grid step must be > 0, got {step_m}")
    rows, cols = model.occupied.shape
    # The message's resolution is a float32 (0.1 is 0.10000000149): 20.000001 cells are 20.
    n_rows = max(1, int(math.ceil(rows * model.resolution / step_m - 1e-4)))
    n_cols = max(1, int(math.ceil(cols * model.resolution / step_m - 1e-4)))
    ox, oy = model.origin_xy
    mbps = np.empty((n_rows, n_cols))
    for r in range(n_rows):
        y = oy + (r + 0.5) * step_m
        for c in range(n_cols):
            mbps[r, c] = model.bandwidth_at(ox + (c + 0.5) * step_m, y)
    return CoverageGrid(mbps, float(step_m), (float(ox), float(oy)))


def parse_schedule(value, name: str = "~schedule") -> ScriptedSchedule:
    """A ScriptedSchedule from a parameter `[[t_s, mbps], ...]`; ValueError names the parameter
    and the bad element."""
    if not isinstance(value, (list, tuple)) or not value:
        raise ValueError(f"{name} must be a non-empty list of [t_s, mbps] pairs, got {value!r}")
    steps = []
    for i, element in enumerate(value):
        if not (isinstance(element, (list, tuple)) and len(element) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                        and math.isfinite(v) for v in element)):
            raise ValueError(f"{name}[{i}] must be a pair of numbers [t_s, mbps], "
                             f"got {element!r}")
        t, mbps = float(element[0]), float(element[1])
        if mbps < 0:
            raise ValueError(f"{name}[{i}]: bandwidth must be >= 0 Mbit/s, got {element!r}")
        if steps and t < steps[-1][0]:
            raise ValueError(f"{name}[{i}]: times must not decrease, got {element!r} after "
                             f"{list(value[i - 1])!r}")
        steps.append((t, mbps))
    return ScriptedSchedule(steps)


def loop_corners(start_xy: Tuple[float, float], goals_xy: Sequence[Tuple[float, float]],
                 leg_is_clear: Optional[Callable[[Tuple[float, float], Tuple[float, float]],
                                                 bool]] = None) -> List[Tuple[float, float]]:
    """The corners of the closed loop start -> goals -> start. With `leg_is_clear`, a leg that
    is not clear (it would cut through walls, as a diagonal between goals on two sides of a
    corridor ring does) goes round the axis-aligned corner whose two legs are clear, the way
    the robot drives along a corridor; without it, legs are straight."""
    goals = [tuple(map(float, g)) for g in goals_xy]
    loop = [tuple(map(float, start_xy))] + goals + [tuple(map(float, start_xy))]
    corners = [loop[0]]
    for a, b in zip(loop, loop[1:]):
        if leg_is_clear is not None and not leg_is_clear(a, b):
            for corner in ((b[0], a[1]), (a[0], b[1])):
                if leg_is_clear(a, corner) and leg_is_clear(corner, b):
                    corners.append(corner)
                    break
        corners.append(b)
    return corners


def path_points(corners: Sequence[Tuple[float, float]], step_m: float = 0.1) -> np.ndarray:
    """(N, 2) points every `step_m` along straight legs between consecutive corners; a leg's
    end point is the next leg's first, so no point is counted twice (nor the closing one)."""
    points = []
    for (ax, ay), (bx, by) in zip(corners, corners[1:]):
        length = math.hypot(bx - ax, by - ay)
        n = int(math.ceil(length / step_m - 1e-9))
        for k in range(n):
            f = k * step_m / length
            points.append((ax + f * (bx - ax), ay + f * (by - ay)))
    return np.asarray(points, dtype=float).reshape(-1, 2)


def leg_clear_on(
        model: CoverageModel) -> Callable[[Tuple[float, float], Tuple[float, float]], bool]:
    """A `leg_is_clear` for loop_corners: no occupied cell of the model's map on the leg."""
    return lambda a, b: walls_crossed(model.occupied, model.resolution, model.origin_xy,
                                      a, b) == 0


def coverage_shares(bandwidth_at: Callable[[float, float], float], points: np.ndarray,
                    thresholds_mbps: Sequence[float] = (3.0, 12.0)) -> Dict[str, float]:
    """Share of the points with any link ('covered') and with at least each threshold
    ('>=3', '>=12', ...), each 0..1."""
    mbps = np.array([bandwidth_at(x, y) for x, y in points])
    shares = {"covered": float(np.mean(mbps > 0))}
    for t in thresholds_mbps:
        shares[f">={t:g}"] = float(np.mean(mbps >= t))
    return shares


MODES = ("coverage", "schedule")


@dataclass(frozen=True)
class ShaperParams:
    """The link_shaper node's private parameters, checked."""
    mode: str
    access_point_xy: Optional[Tuple[float, float]]    # coverage mode
    schedule: Optional[ScriptedSchedule]               # schedule mode
    rate_hz: float
    layout: TwoScaleLayout
    burst_kbit: int
    dry_run: bool
    seed: int = 0       # coverage mode: 0 = the deterministic model, else wifi_variation's
    map_file: str = ""  # coverage mode: the floor plan's map YAML; "" = from /map


SHAPER_PARAMS = (
    Param("mode", "coverage", "coverage: bandwidth from the robot's pose; schedule: scripted",
          kind="choice", choices=MODES),
    Param("access_point_x", REQUIRED, "access point in the map frame (coverage mode)", "m",
          kind="float"),
    Param("access_point_y", REQUIRED, "access point in the map frame (coverage mode)", "m",
          kind="float"),
    Param("schedule", REQUIRED, "[[t_s, mbps], ...] (schedule mode)", kind="raw"),
    Param("rate_hz", 5.0, "how often the link is set", "Hz", minimum=0.0, above=True),
    Param("burst_kbit", 32, "tbf burst", "kbit", minimum=1),
    Param("dry_run", False, "log the tc commands instead of running them"),
    Param("seed", 0, "coverage mode: 0 = the deterministic model, else wifi_variation's",
          minimum=0),
    Param("robot_namespace", TwoScaleLayout().robot.namespace, "the robot's netns", kind="name"),
    Param("robot_interface", TwoScaleLayout().robot.interface, "its veth end", kind="name"),
    # The WiFi veth's far end: the laptop's on two scales, the access point's on three
    # (access_point_layout.py; testbed_world.launch's wifi_peer_* args).
    Param("laptop_namespace", TwoScaleLayout().laptop.namespace,
          "the netns of the WiFi veth's far end", kind="name"),
    Param("laptop_interface", TwoScaleLayout().laptop.interface, "that end's interface",
          kind="name"),
    Param("map_file", "", "coverage mode: the floor plan's map YAML; empty: from /map",
          kind="raw"),
)
_SHAPER = {p.name: p for p in SHAPER_PARAMS}


def read_shaper_params(get: Callable[[str, object], object]) -> ShaperParams:
    """The node's parameters through `get(name, default)` (rospy.get_param); ValueError
    (ParamError) names the bad parameter. The access point is needed in coverage mode, the
    schedule in schedule mode; there is no sensible default for either."""
    def read(name):
        return _SHAPER[name].read(get)

    mode = read("mode")
    access_point = schedule = None
    if mode == "coverage":
        access_point = (read("access_point_x"), read("access_point_y"))
    else:
        schedule = parse_schedule(get("~schedule", None), "~schedule")
    seed = read("seed")
    if seed and mode != "coverage":
        raise ParamError(f"~seed: varies the coverage model; it has no meaning in {mode} mode")
    default = TwoScaleLayout()
    layout = TwoScaleLayout(
        robot=replace(default.robot, namespace=read("robot_namespace"),
                      interface=read("robot_interface")),
        laptop=replace(default.laptop, namespace=read("laptop_namespace"),
                       interface=read("laptop_interface")))
    map_file = read("map_file")
    if not isinstance(map_file, str):
        raise ParamError(f"~map_file: expected the path of a map YAML, got {map_file!r}")
    if map_file and mode != "coverage":
        raise ParamError(f"~map_file: the coverage model's floor plan; it has no meaning in "
                         f"{mode} mode")
    return ShaperParams(mode, access_point, schedule, read("rate_hz"), layout,
                        read("burst_kbit"), read("dry_run"), seed, map_file)
