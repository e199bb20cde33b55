"""AMCL's obstacle distances of a map, kept on disk for the next AMCL instance.

Every AMCL instance turns the map into a likelihood field (a Euclidean distance transform of
the occupied cells): for an 811 x 811 map like the office floor's, 0.05-0.06 s of CPU on this
machine without a quota. An instance brought back to the starved robot by a link loss gets
about a tenth of a core there, which makes that half a second of wall time before its first
pose, against a two-second tolerance. The map does not change between instances, so the
distances are stored under a key of the map's content and read back by the next instance.
"""
import hashlib
import os
import tempfile
from typing import Callable, Optional

import numpy as np


def map_key(occupied: np.ndarray, resolution: float, max_dist: float) -> str:
    """A name for what the distances depend on: the occupied cells, cell size and cap."""
    h = hashlib.sha1()
    h.update(np.ascontiguousarray(occupied, dtype=bool).tobytes())
    h.update(np.array(occupied.shape + (resolution, max_dist), dtype=float).tobytes())
    return h.hexdigest()


def cached_distances(occupied: np.ndarray, resolution: float, max_dist: float,
                     cache_dir: Optional[str],
                     compute: Callable[[], np.ndarray]) -> np.ndarray:
    """The distances from `cache_dir` if an earlier instance stored them for this map, else
    compute() stored there for the next one. Without a usable cache_dir (None, unwritable,
    a damaged file) it computes and goes on: the cache only ever saves time."""
    if not cache_dir:
        return compute()
    path = os.path.join(cache_dir, f"likelihood_{map_key(occupied, resolution, max_dist)}.npy")
    try:
        dist = np.load(path, allow_pickle=False)
        if dist.shape == occupied.shape:
            return dist
    except (OSError, ValueError):
        pass                                # not there yet, or damaged: computed again
    dist = compute()
    try:
        os.makedirs(cache_dir, exist_ok=True)
        # Written aside and renamed: an instance reading at the same time never sees half.
        fd, tmp = tempfile.mkstemp(dir=cache_dir, suffix=".npy.tmp")
        with os.fdopen(fd, "wb") as f:
            np.save(f, dist, allow_pickle=False)
        os.replace(tmp, path)
    except OSError:
        pass
    return dist
