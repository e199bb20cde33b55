"""Generates the test-bed floors: a square corridor loop with rooms, a lab and 4 AR markers."""
import math

import numpy as np

from .occupancy_map import FREE, OCCUPIED, UNKNOWN, OccupancyMap


class FloorPlan:
    """A loop floor: its occupancy map plus where markers, start, goals and the lab are."""

    def __init__(self, occ_map, markers, start, goals, lab):
        self.map = occ_map
        self.markers = markers      # [{id, x, y, yaw (wall normal, into the corridor), size}]
        self.start = start          # (x, y, yaw): point A, also point B (the loop is closed)
        self.goals = goals          # [(x, y, yaw, marker_id or -1)], counter-clockwise
        self.lab = lab              # {x, y}: where the laptop and access point sit

    def world(self):
        """The simulator/launch description (YAML-able)."""
        return {"markers": self.markers,
                "start": list(self.start),
                "goals": [list(g) for g in self.goals],
                "lab": self.lab}


def _fill(grid, res, x0, y0, x1, y1, value):
    """Set every cell whose centre lies in the world rectangle [x0,x1]x[y0,y1]."""
    c0, c1 = int(round(min(x0, x1) / res)), int(round(max(x0, x1) / res))
    r0, r1 = int(round(min(y0, y1) / res)), int(round(max(y0, y1) / res))
    grid[max(r0, 0):max(r1, 0), max(c0, 0):max(c1, 0)] = value


def make_loop_floor(side=28.75, corridor=2.0, room_depth=4.0, room_width=4.0, margin=0.5,
                    wall=0.2, door=0.9, resolution=0.05, marker_size=0.4, closed_door_every=3,
                    inner_rooms=True):
    """A square corridor loop (centre line 4 * side long) between an outer and an inner ring
    of rooms, each room with a single door onto the corridor (so no short cuts), a solid core,
    the lab as the middle inner room of the north side, and a marker half-way along each side
    on the corridor's outer wall. Navigation is counter-clockwise from A in the south-west.
    """
    c0 = margin + wall + room_depth + wall + corridor / 2.0      # centre line of south/west legs
    c1 = c0 + side
    size = c1 + corridor / 2.0 + wall + room_depth + wall + margin
    n = int(math.ceil(size / resolution))
    grid = np.full((n, n), UNKNOWN, dtype=np.int8)
    res = resolution
    lo_out, hi_out = margin, size - margin                        # building shell
    _fill(grid, res, lo_out, lo_out, hi_out, hi_out, OCCUPIED)
    _fill(grid, res, lo_out + wall, lo_out + wall, hi_out - wall, hi_out - wall, FREE)
    in_lo, in_hi = c0 + corridor / 2.0, c1 - corridor / 2.0          # inner corridor walls
    out_lo, out_hi = c0 - corridor / 2.0, c1 + corridor / 2.0        # outer corridor walls
    _ring(grid, res, out_lo - wall, out_hi + wall, wall)             # corridor outer wall
    _ring(grid, res, in_lo, in_hi, wall)                             # corridor inner wall
    core = wall + room_depth if inner_rooms else 0.0
    _fill(grid, res, in_lo + core, in_lo + core, in_hi - core, in_hi - core, OCCUPIED)  # solid core
    if inner_rooms:  # corner squares of the inner band: stairs and lifts, solid
        for x in (in_lo, in_hi - core):
            for y in (in_lo, in_hi - core):
                _fill(grid, res, x, y, x + core, y + core, OCCUPIED)
    mid = (c0 + c1) / 2.0
    markers = [
        {"id": 0, "x": mid, "y": out_lo, "yaw": math.pi / 2, "size": marker_size},
        {"id": 1, "x": out_hi, "y": mid, "yaw": math.pi, "size": marker_size},
        {"id": 2, "x": mid, "y": out_hi, "yaw": -math.pi / 2, "size": marker_size},
        {"id": 3, "x": out_lo, "y": mid, "yaw": 0.0, "size": marker_size},
    ]
    _partitions_and_doors(grid, res, c0, c1, corridor, wall, room_depth, room_width, door,
                          markers, closed_door_every, inner_rooms)
    start = (c0 + 1.5, c0, 0.0)
    # Goals in front of each marker, facing it, so the camera sees it square on if it has
    # not already recognised it on the way; then back to A.
    goals = [(mid, c0, -math.pi / 2, 0), (c1, mid, 0.0, 1), (mid, c1, math.pi / 2, 2),
             (c0, mid, math.pi, 3), (start[0], start[1], start[2], -1)]
    lab = {"x": mid, "y": in_hi - wall - room_depth / 2.0 if inner_rooms else c1}
    return FloorPlan(OccupancyMap(grid, res, (0.0, 0.0, 0.0)), markers, start, goals, lab)


def _ring(grid, res, lo, hi, wall):
    """Square wall ring: outer edge lo..hi, thickness wall."""
    _fill(grid, res, lo, lo, hi, lo + wall, OCCUPIED)
    _fill(grid, res, lo, hi - wall, hi, hi, OCCUPIED)
    _fill(grid, res, lo, lo, lo + wall, hi, OCCUPIED)
    _fill(grid, res, hi - wall, lo, hi, hi, OCCUPIED)


def _partitions_and_doors(grid, res, c0, c1, corridor, wall, depth, width, door, markers, every,
                          inner_rooms):
    """Rooms along each leg: partition walls and one door per room (none at a marker).

    Each band of rooms is split into legs that do not share a room, so a room never has
    doors onto two legs (which would give the planner a short cut across a corner).
    """
    if depth <= 0:
        return
    out_lo, out_hi = c0 - corridor / 2.0, c1 + corridor / 2.0
    in_lo, in_hi = c0 + corridor / 2.0, c1 - corridor / 2.0
    marker_s = (c0 + c1) / 2.0
    bands = [(True, out_lo - wall, out_hi + wall)]
    if inner_rooms:
        bands.append((False, in_lo + wall + depth, in_hi - wall - depth))
    count = 0
    for side in range(4):
        for outer, lo, hi in bands:
            n_rooms = max(1, int(round((hi - lo) / width)))
            edges = np.linspace(lo, hi, n_rooms + 1)
            for e in edges:
                _partition(grid, res, side, outer, e, wall, depth, out_lo, out_hi, in_lo, in_hi)
            for a0, a1 in zip(edges[:-1], edges[1:]):
                count += 1
                door_mid = (a0 + a1) / 2.0
                if (outer and abs(door_mid - marker_s) < 1.0) or count % every == 0:
                    continue  # the marker's wall, or a closed door
                _door(grid, res, side, outer, door_mid, door, wall, out_lo, out_hi, in_lo, in_hi)


def _door(grid, res, side, outer, s, door, wall, out_lo, out_hi, in_lo, in_hi):
    """Open a door gap in the corridor wall at position s along the given leg."""
    w = [out_lo - wall, out_lo] if outer else [in_lo, in_lo + wall]
    w_hi = [out_hi, out_hi + wall] if outer else [in_hi - wall, in_hi]
    a, b = s - door / 2.0, s + door / 2.0
    if side == 0:
        _fill(grid, res, a, w[0], b, w[1], FREE)
    elif side == 1:
        _fill(grid, res, w_hi[0], a, w_hi[1], b, FREE)
    elif side == 2:
        _fill(grid, res, a, w_hi[0], b, w_hi[1], FREE)
    else:
        _fill(grid, res, w[0], a, w[1], b, FREE)


def _partition(grid, res, side, outer, s, wall, depth, out_lo, out_hi, in_lo, in_hi):
    """A wall between two rooms, perpendicular to the corridor, at position s along the leg."""
    if outer:
        span_lo, span_hi = (out_lo - 2 * wall - depth, out_lo), (out_hi, out_hi + 2 * wall + depth)
    else:
        span_lo, span_hi = (in_lo, in_lo + wall + depth), (in_hi - wall - depth, in_hi)
    h = wall / 2.0
    if side == 0:
        _fill(grid, res, s - h, span_lo[0], s + h, span_lo[1], OCCUPIED)
    elif side == 1:
        _fill(grid, res, span_hi[0], s - h, span_hi[1], s + h, OCCUPIED)
    elif side == 2:
        _fill(grid, res, s - h, span_hi[0], s + h, span_hi[1], OCCUPIED)
    else:
        _fill(grid, res, span_lo[0], s - h, span_lo[1], s + h, OCCUPIED)
