"""The demo's rviz view framed on a map: the saved top-down view's focal point and scale chosen so
that the map's whole extent fits rviz's render panel, whatever the world (no ROS; the launcher is
nodes/rviz_for_map). rviz takes a view only from its config file, not from an argument."""
import math
import re
from dataclasses import dataclass
from typing import Sequence, Tuple

import yaml

from .occupancy_map import load_map

# nav_demo.rviz lays out a 1280x800 window with the camera and the displays docked on the left:
# its render panel is 900 x 708 px (measured on a screenshot under Xvfb).
RENDER_PANEL_PX = (900, 708)
# The share of the panel's shorter fit the map may fill, so that its border stays in view.
FILL = 0.92
VIEW_KEYS = ("X", "Y", "Scale")


class ViewError(ValueError):
    """The rviz config has no single top-down view whose X, Y and Scale can be set; names it."""


@dataclass(frozen=True)
class View:
    x: float        # focal point in the fixed frame, m
    y: float
    scale: float    # px per m


def map_extent(map_yaml: str) -> Tuple[float, float, float, float]:
    """(x_min, y_min, x_max, y_max) in the map frame of a map_server YAML's grid, its origin's yaw
    included; MapError (occupancy_map) names the file and what is wrong."""
    occ = load_map(map_yaml)
    x0, y0, yaw = occ.origin
    w, h = occ.width * occ.resolution, occ.height * occ.resolution
    c, s = math.cos(yaw), math.sin(yaw)
    xs, ys = zip(*((x0 + c * u - s * v, y0 + s * u + c * v)
                   for u, v in ((0, 0), (w, 0), (0, h), (w, h))))
    return min(xs), min(ys), max(xs), max(ys)


def framing(extent: Sequence[float], panel_px=RENDER_PANEL_PX, fill: float = FILL) -> View:
    """The view centred on `extent` at the largest scale that shows all of it in `panel_px`."""
    x_min, y_min, x_max, y_max = extent
    width, height = x_max - x_min, y_max - y_min
    if not (width > 0 and height > 0):
        raise ValueError(f"map extent {tuple(extent)}: expected a positive width and height")
    scale = fill * min(panel_px[0] / width, panel_px[1] / height)
    return View((x_min + x_max) / 2, (y_min + y_max) / 2, round(scale, 3))


def framed_config(text: str, view: View, where: str = "rviz config") -> str:
    """`text` (an rviz config) with its current view's X, Y and Scale set to `view`; every other
    byte kept. ViewError if the config has no top-down view with those keys."""
    match = re.search(r"^( *)Views:\n\1  Current:\n((?:\1    .*\n)+)", text, re.M)
    if not match:
        raise ViewError(f"{where}: no 'Views: Current:' block")
    block, indent = match.group(2), match.group(1) + "    "
    values = {"X": f"{view.x:g}", "Y": f"{view.y:g}", "Scale": f"{view.scale:g}"}
    for key in VIEW_KEYS:
        block, n = re.subn(rf"^{indent}{key}: .*$", f"{indent}{key}: {values[key]}", block,
                           flags=re.M)
        if n != 1:
            raise ViewError(f"{where}: the current view has no single '{key}:' (a top-down "
                            f"view, rviz/TopDownOrtho, has X, Y and Scale)")
    framed = text[:match.start(2)] + block + text[match.end(2):]
    current = yaml.safe_load(framed)["Visualization Manager"]["Views"]["Current"]
    if current.get("Class") != "rviz/TopDownOrtho":
        raise ViewError(f"{where}: the current view is {current.get('Class')!r}, not "
                        f"rviz/TopDownOrtho")
    return framed
