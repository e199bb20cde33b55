"""The link to each remote scale as the robot met it along its route: a grid over the map's
frame, per remote scale, of the agents' link observations (time, place, bandwidth, lost) with
a conservative statistic per cell, saved and loaded as a YAML file the way map_server keeps an
occupancy grid, so a later run starts with what an earlier one learned (no ROS)."""
from collections import deque
from dataclasses import dataclass
import math
import os
from typing import Deque, Dict, Iterator, List, Optional, Tuple

import numpy as np
import yaml

from .param_spec import declared

FILE_FORMAT = "anyscale_link_map"
FILE_VERSION = 1

Cell = Tuple[int, int]
# t (wall clock, s since the epoch: a map outlives the run), x, y (m), Mbit/s (0 if lost), lost
Observation = Tuple[float, float, float, float, bool]


class LinkMapError(ValueError):
    """A link map file that is missing or cannot be read; the message names the file and what
    was wrong with it."""


@dataclass(frozen=True)
class LinkMapParams:
    """The link map's grid and statistic, each parameter declared once (param_spec). A map is
    reused by later runs, days later too: a cell whose link changed is relearned from its
    newest observations, so the age only bounds what is kept of places no longer driven."""
    resolution_m: float = declared(1.0, "the link map's cell size", "m",
                                   name="link_map_resolution_m", minimum=0.01)
    quantile: float = declared(
        0.1, "a cell's figure: this low quantile of its observations, a loss counting as 0",
        "0..1", name="link_map_quantile", minimum=0.0, maximum=1.0)
    cell_observations: int = declared(30, "each cell keeps its newest observations, this many",
                                      name="link_map_cell_observations", minimum=1)
    min_observations: int = declared(3, "a cell with fewer observations is unknown",
                                     name="link_map_min_observations", minimum=1)
    max_age_s: float = declared(7 * 86400.0, "older observations are dropped", "s",
                                name="link_map_max_age_s", minimum=1.0)
    hole_lost_fraction: float = declared(
        0.0, "a cell whose link was lost in more than this share of its observations is a hole "
        "(a blip is one observation of a pass, but it was met on that pass)", "0..1",
        name="link_map_hole_lost_fraction", minimum=0.0, maximum=1.0)
    hole_margin_cells: int = declared(
        1, "a cell within this many cells of a hole clears no node to skip the reactive rules "
        "(a coverage edge flickers from lap to lap, beside where it was lost before)", "cells",
        name="link_map_hole_margin_cells", minimum=0)


@dataclass(frozen=True)
class CellStats:
    low_mbps: float         # the quantile of the cell's bandwidth, losses counted as 0
    lost_fraction: float    # share of its observations with the link lost
    count: int


class LinkMap:
    """Per remote scale, each cell's newest observations. Not thread-safe: the caller locks."""

    def __init__(self, params: LinkMapParams = LinkMapParams(), frame_id: str = "map"):
        self.params = params
        self.frame_id = frame_id
        self._cells: Dict[str, Dict[Cell, Deque[Observation]]] = {}
        self._stats: Dict[Tuple[str, Cell], Optional[CellStats]] = {}

    def cell_of(self, x: float, y: float) -> Cell:
        r = self.params.resolution_m
        return int(math.floor(x / r)), int(math.floor(y / r))

    def centre_of(self, cell: Cell) -> Tuple[float, float]:
        r = self.params.resolution_m
        return (cell[0] + 0.5) * r, (cell[1] + 0.5) * r

    def add(self, scale: str, t: float, x: float, y: float, mbps: float, lost: bool):
        """One observation of `scale`'s link with the robot at (x, y). A lost link counts as
        0 Mbit/s; one that is up needs a finite bandwidth (ValueError otherwise)."""
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(t)):
            raise ValueError(f"link observation at ({x}, {y}), t={t}: not finite")
        if not lost and not (math.isfinite(mbps) and mbps >= 0):
            raise ValueError(f"link observation of {scale}: bandwidth {mbps!r} Mbit/s")
        cell = self.cell_of(x, y)
        cells = self._cells.setdefault(scale, {})
        kept = cells.get(cell)
        if kept is None:
            kept = cells[cell] = deque(maxlen=self.params.cell_observations)
        kept.append((float(t), float(x), float(y), 0.0 if lost else float(mbps), bool(lost)))
        self._stats.pop((scale, cell), None)

    def age_out(self, now: float):
        """Drops observations older than max_age_s (now: wall clock), and emptied cells."""
        oldest = now - self.params.max_age_s
        for scale, cells in self._cells.items():
            for cell in list(cells):
                fresh = [o for o in cells[cell] if o[0] >= oldest]
                if len(fresh) == len(cells[cell]):
                    continue
                if fresh:
                    cells[cell] = deque(fresh, maxlen=self.params.cell_observations)
                else:
                    del cells[cell]
                self._stats.pop((scale, cell), None)

    def stats(self, scale: str, cell: Cell) -> Optional[CellStats]:
        """The cell's figures; None while it has fewer than min_observations (unknown)."""
        key = (scale, cell)
        if key not in self._stats:
            kept = self._cells.get(scale, {}).get(cell, ())
            if len(kept) < self.params.min_observations:
                self._stats[key] = None
            else:
                mbps = np.array([o[3] for o in kept])
                lost = sum(o[4] for o in kept)
                # "lower": an observed value, never one interpolated above it.
                low = float(np.quantile(mbps, self.params.quantile, method="lower"))
                self._stats[key] = CellStats(low, lost / len(kept), len(kept))
        return self._stats[key]

    def is_hole(self, stats: Optional[CellStats]) -> bool:
        """A known cell whose link was lost in more than hole_lost_fraction of its
        observations."""
        return stats is not None and stats.lost_fraction > self.params.hole_lost_fraction

    def beside_hole(self, scale: str, cell: Cell) -> bool:
        """Whether a hole lies within hole_margin_cells of the cell (the cell itself left out)."""
        m = self.params.hole_margin_cells
        return any(self.is_hole(self.stats(scale, (cell[0] + dx, cell[1] + dy)))
                   for dx in range(-m, m + 1) for dy in range(-m, m + 1) if dx or dy)

    def scales(self) -> List[str]:
        return sorted(s for s, cells in self._cells.items() if cells)

    def known_cells(self, scale: str) -> Iterator[Tuple[Cell, CellStats]]:
        """Every cell of `scale` with enough observations, and its figures."""
        for cell in sorted(self._cells.get(scale, {})):
            s = self.stats(scale, cell)
            if s is not None:
                yield cell, s

    def observation_count(self) -> int:
        return sum(len(k) for cells in self._cells.values() for k in cells.values())

    # --- the file -----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        p = self.params
        return {"format": FILE_FORMAT, "version": FILE_VERSION, "frame_id": self.frame_id,
                "resolution": p.resolution_m,
                "statistic": {"quantile": p.quantile, "cell_observations": p.cell_observations,
                              "min_observations": p.min_observations, "max_age_s": p.max_age_s},
                "scales": {scale: [{"cell": list(cell),
                                    "observations": [_rounded(o) for o in cells[cell]]}
                                   for cell in sorted(cells)]
                           for scale, cells in sorted(self._cells.items()) if cells}}

    def save(self, path: str):
        """Writes the map whole or not at all (write_link_map)."""
        write_link_map(self.to_dict(), path)


def write_link_map(data: dict, path: str):
    """Writes a map's to_dict() whole or not at all: a temporary file beside it, then renamed
    (the caller may take the dict under its lock and write outside it)."""
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            yaml.dump(data, f, Dumper=_Dumper, default_flow_style=None, sort_keys=False,
                      width=100)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def _rounded(o: Observation) -> list:
    """An observation as the file keeps it: 10 ms, 1 cm, 0.01 Mbit/s."""
    t, x, y, mbps, lost = o
    return [round(t, 2), round(x, 2), round(y, 2), round(mbps, 2), int(lost)]


_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def load_link_map(path: str, params: LinkMapParams = LinkMapParams(), frame_id: str = "map",
                  now: Optional[float] = None) -> LinkMap:
    """The map saved in `path`, its observations kept under `params` (a file of another
    resolution is put on this grid from each observation's place) and aged as of `now` (wall
    clock; None: not aged). LinkMapError names the file and what was wrong."""
    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.load(f, Loader=_Loader)
    except FileNotFoundError:
        raise LinkMapError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise LinkMapError(f"{path}: cannot read: {e}") from None
    except yaml.YAMLError as e:
        raise LinkMapError(f"{path}: not YAML: {str(e).splitlines()[0]}") from None
    link_map = LinkMap(params, frame_id)
    for scale, t, x, y, mbps, lost in _observations(data, path, frame_id):
        link_map.add(scale, t, x, y, mbps, lost)
    if now is not None:
        link_map.age_out(now)
    return link_map


def _observations(data, path: str, frame_id: str):
    """Every observation of a loaded file, checked, oldest first per cell."""
    def bad(key: str, what: str):
        return LinkMapError(f"{path}: {key}: {what}")
    if not isinstance(data, dict):
        raise LinkMapError(f"{path}: expected a mapping, got {type(data).__name__}")
    if data.get("format") != FILE_FORMAT:
        raise bad("format", f"expected {FILE_FORMAT!r}, got {data.get('format')!r}")
    if data.get("version") != FILE_VERSION:
        raise bad("version", f"expected {FILE_VERSION}, got {data.get('version')!r}")
    if data.get("frame_id") != frame_id:
        raise bad("frame_id", f"the map is in {data.get('frame_id')!r}, expected {frame_id!r}")
    resolution = data.get("resolution")
    if not _number(resolution) or not resolution > 0:
        raise bad("resolution", f"expected a number > 0, got {resolution!r}")
    scales = data.get("scales")
    if not isinstance(scales, dict):
        raise bad("scales", f"expected a mapping of scale names, got {type(scales).__name__}")
    out: List[Tuple[str, float, float, float, float, bool]] = []
    for scale, cells in scales.items():
        if not isinstance(cells, list):
            raise bad(f"scales.{scale}", "expected a list of cells")
        for k, entry in enumerate(cells):
            key = f"scales.{scale}[{k}]"
            if not isinstance(entry, dict) or not isinstance(entry.get("observations"), list):
                raise bad(key, "expected {cell: [i, j], observations: [[t, x, y, mbps, lost]]}")
            for n, o in enumerate(entry["observations"]):
                if not (isinstance(o, list) and len(o) == 5 and all(_number(v) for v in o)
                        and o[4] in (0, 1) and all(math.isfinite(v) for v in o) and o[3] >= 0):
                    raise bad(f"{key}.observations[{n}]",
                              f"expected [t, x, y, mbps >= 0, lost 0|1], got {o!r}")
                out.append((str(scale), float(o[0]), float(o[1]), float(o[2]), float(o[3]),
                            bool(o[4])))
    out.sort(key=lambda o: o[1])     # newest last: a cell's cap keeps the newest
    return out


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)
