"""Occupancy grid maps with map_server's file semantics (YAML + PGM): load, save, index."""
import os

import numpy as np
import yaml

OCCUPIED, FREE, UNKNOWN = 100, 0, -1


class MapError(Exception):
    """A map file is missing or malformed; the message names the file and the problem."""


class OccupancyMap:
    """A grid in nav_msgs/OccupancyGrid order: data[row, col], row 0 at origin y (bottom)."""

    def __init__(self, data, resolution, origin=(0.0, 0.0, 0.0)):
        self.data = np.asarray(data, dtype=np.int8)
        if self.data.ndim != 2:
            raise ValueError("map data must be 2-D")
        self.resolution = float(resolution)
        self.origin = tuple(float(v) for v in origin)

    @property
    def height(self):
        return self.data.shape[0]

    @property
    def width(self):
        return self.data.shape[1]

    @property
    def occupied(self):
        """Cells that block the laser and the robot (unknown counts as free space for rays)."""
        return self.data >= 50

    @property
    def free(self):
        return self.data == FREE

    def world_to_cell(self, x, y):
        """(col, row) integer indices of world points (may be outside the grid)."""
        col = np.floor((np.asarray(x) - self.origin[0]) / self.resolution).astype(int)
        row = np.floor((np.asarray(y) - self.origin[1]) / self.resolution).astype(int)
        return col, row

    def cell_center(self, col, row):
        """World coordinates of cell centres."""
        return (self.origin[0] + (np.asarray(col) + 0.5) * self.resolution,
                self.origin[1] + (np.asarray(row) + 0.5) * self.resolution)

    def inside(self, col, row):
        return (col >= 0) & (col < self.width) & (row >= 0) & (row < self.height)

    def is_occupied_at(self, x, y):
        """True where a world point lies in an occupied cell or off the map."""
        col, row = self.world_to_cell(x, y)
        ok = self.inside(col, row)
        out = np.ones(np.shape(col), dtype=bool)
        out[ok] = self.occupied[row[ok], col[ok]]
        return out


def _read_pgm(path):
    """Grey image (rows top to bottom) from a binary (P5) or ASCII (P2) PGM file."""
    with open(path, "rb") as f:
        raw = f.read()
    tokens, pos = [], 0
    while len(tokens) < 4:
        while pos < len(raw) and raw[pos:pos + 1].isspace():
            pos += 1
        if pos < len(raw) and raw[pos:pos + 1] == b"#":
            while pos < len(raw) and raw[pos:pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < len(raw) and not raw[pos:pos + 1].isspace():
            pos += 1
        if start == pos:
            raise MapError("%s: truncated PGM header" % path)
        tokens.append(raw[start:pos])
    magic = tokens[0]
    if magic not in (b"P5", b"P2"):
        raise MapError("%s: not a PGM image (magic %r, expected P5 or P2)" % (path, magic))
    try:
        width, height, maxval = (int(t) for t in tokens[1:4])
    except ValueError:
        raise MapError("%s: malformed PGM header %r" % (path, tokens[1:4]))
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise MapError("%s: bad PGM size %dx%d or maxval %d" % (path, width, height, maxval))
    if magic == b"P5":
        dtype = np.uint8 if maxval < 256 else np.dtype(">u2")
        body = raw[pos + 1:]
        need = width * height * np.dtype(dtype).itemsize
        if len(body) < need:
            raise MapError("%s: PGM data truncated (%d of %d bytes)" % (path, len(body), need))
        img = np.frombuffer(body[:need], dtype=dtype).reshape(height, width)
    else:
        values = raw[pos:].split()
        if len(values) < width * height:
            raise MapError("%s: PGM data truncated (%d of %d values)"
                           % (path, len(values), width * height))
        img = np.array([int(v) for v in values[:width * height]]).reshape(height, width)
    return img.astype(np.float64) * (255.0 / maxval)


def _read_image(path):
    """Grey image 0..255 (rows top to bottom); PGM natively, other formats through OpenCV."""
    if not os.path.isfile(path):
        raise MapError("%s: map image not found" % path)
    if path.lower().endswith(".pgm"):
        return _read_pgm(path)
    import cv2  # only for PNG and friends
    img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise MapError("%s: cannot decode map image" % path)
    return img.astype(np.float64)


def _require(meta, key, kind, yaml_path):
    if key not in meta:
        raise MapError("%s: missing key '%s'" % (yaml_path, key))
    try:
        return kind(meta[key])
    except (TypeError, ValueError):
        raise MapError("%s: key '%s' must be %s, got %r"
                       % (yaml_path, key, kind.__name__, meta[key]))


def grey_to_occupancy(grey, negate, occupied_thresh, free_thresh, mode="trinary"):
    """map_server's pixel rule: p = (255 - v) / 255 (v inverted if negate); thresholds on p."""
    value = 255.0 - grey if negate else grey
    if mode == "raw":
        return np.clip(np.round(value), -1, 100).astype(np.int8)
    occ = (255.0 - value) / 255.0
    out = np.full(grey.shape, UNKNOWN, dtype=np.int8)
    if mode == "scale":
        ratio = (occ - free_thresh) / (occupied_thresh - free_thresh)
        mid = (occ > free_thresh) & (occ < occupied_thresh)
        out[mid] = (1 + 98 * ratio[mid]).astype(np.int8)
    out[occ > occupied_thresh] = OCCUPIED
    out[occ < free_thresh] = FREE
    return out


def read_yaml_mapping(path, what, expected):
    """The YAML mapping in a file; MapError names the file and what is wrong (`what` names the
    kind of file, `expected` the keys it should have)."""
    if not os.path.isfile(path):
        raise MapError("%s: %s not found" % (path, what))
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise MapError("%s: malformed YAML (%s)" % (path, str(e).splitlines()[0]))
    if not isinstance(data, dict):
        raise MapError("%s: expected a mapping with %s" % (path, expected))
    return data


def load_map(yaml_path):
    """OccupancyMap from a map_server YAML file; MapError names the file and what is wrong."""
    meta = read_yaml_mapping(yaml_path, "map YAML", "image, resolution, origin, ...")
    image = _require(meta, "image", str, yaml_path)
    resolution = _require(meta, "resolution", float, yaml_path)
    if resolution <= 0:
        raise MapError("%s: resolution must be > 0, got %g" % (yaml_path, resolution))
    origin = meta.get("origin")
    if not (isinstance(origin, (list, tuple)) and len(origin) == 3):
        raise MapError("%s: key 'origin' must be [x, y, yaw], got %r" % (yaml_path, origin))
    try:
        origin = tuple(float(v) for v in origin)
    except (TypeError, ValueError):
        raise MapError("%s: key 'origin' must hold three numbers, got %r" % (yaml_path, origin))
    negate = _require(meta, "negate", int, yaml_path)
    occ_th = _require(meta, "occupied_thresh", float, yaml_path)
    free_th = _require(meta, "free_thresh", float, yaml_path)
    if not 0.0 <= free_th < occ_th <= 1.0:
        raise MapError("%s: need 0 <= free_thresh < occupied_thresh <= 1, got %g and %g"
                       % (yaml_path, free_th, occ_th))
    mode = str(meta.get("mode", "trinary"))
    if mode not in ("trinary", "scale", "raw"):
        raise MapError("%s: key 'mode' must be trinary, scale or raw, got %r" % (yaml_path, mode))
    image_path = image if os.path.isabs(image) else os.path.join(os.path.dirname(yaml_path), image)
    grey = _read_image(image_path)
    data = grey_to_occupancy(grey, negate, occ_th, free_th, mode)
    # Image row 0 is the top of the picture (max y); OccupancyGrid row 0 is at origin y.
    return OccupancyMap(np.flipud(data), resolution, origin)


def save_map(occ_map, yaml_path, image_name=None):
    """Write map_saver-style PGM (occupied 0, free 254, unknown 205) and YAML."""
    image_name = image_name or os.path.splitext(os.path.basename(yaml_path))[0] + ".pgm"
    grey = np.full(occ_map.data.shape, 205, dtype=np.uint8)
    grey[occ_map.data == FREE] = 254
    grey[occ_map.data >= 50] = 0
    grey = np.flipud(grey)
    pgm_path = os.path.join(os.path.dirname(yaml_path), image_name)
    with open(pgm_path, "wb") as f:
        f.write(b"P5\n# anyscale_nav_demo map\n%d %d\n255\n" % (grey.shape[1], grey.shape[0]))
        f.write(grey.tobytes())
    meta = {"image": image_name, "resolution": occ_map.resolution, "origin": list(occ_map.origin),
            "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196}
    with open(yaml_path, "w") as f:
        yaml.safe_dump(meta, f, default_flow_style=None)
