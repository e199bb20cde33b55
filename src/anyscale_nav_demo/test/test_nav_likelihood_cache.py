"""AMCL's obstacle distances are computed once per map and read back by the next instance;
the cache never changes the result and never stands in the way."""
import os

import numpy as np

from anyscale_nav_demo.likelihood_cache import cached_distances, map_key
from anyscale_nav_demo.occupancy_map import OccupancyMap
from anyscale_nav_demo.particle_filter import LikelihoodField, obstacle_distances


def small_map(seed=0):
    rng = np.random.default_rng(seed)
    data = np.where(rng.random((60, 80)) < 0.05, 100, 0).astype(np.int8)
    return OccupancyMap(data, 0.05, (0.0, 0.0, 0.0))


class Counting:
    def __init__(self, occ, max_dist):
        self.occ, self.max_dist, self.calls = occ, max_dist, 0

    def __call__(self):
        self.calls += 1
        return obstacle_distances(self.occ, self.max_dist)


def test_the_second_instance_reads_what_the_first_computed(tmp_path):
    occ = small_map()
    first, second = Counting(occ, 2.0), Counting(occ, 2.0)
    a = cached_distances(occ.occupied, occ.resolution, 2.0, str(tmp_path), first)
    b = cached_distances(occ.occupied, occ.resolution, 2.0, str(tmp_path), second)
    assert (first.calls, second.calls) == (1, 0)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(LikelihoodField(occ, 2.0, b).padded,
                                  LikelihoodField(occ, 2.0).padded)


def test_another_map_or_cap_is_computed_anew(tmp_path):
    occ, other = small_map(0), small_map(1)
    assert map_key(occ.occupied, 0.05, 2.0) != map_key(other.occupied, 0.05, 2.0)
    assert map_key(occ.occupied, 0.05, 2.0) != map_key(occ.occupied, 0.05, 1.0)
    assert map_key(occ.occupied, 0.05, 2.0) != map_key(occ.occupied, 0.1, 2.0)
    cached_distances(occ.occupied, 0.05, 2.0, str(tmp_path), Counting(occ, 2.0))
    again = Counting(other, 2.0)
    cached_distances(other.occupied, 0.05, 2.0, str(tmp_path), again)
    assert again.calls == 1


def test_a_damaged_file_or_an_unusable_directory_only_costs_the_computation(tmp_path):
    occ = small_map()
    cached_distances(occ.occupied, 0.05, 2.0, str(tmp_path), Counting(occ, 2.0))
    (stored,) = tmp_path.glob("likelihood_*.npy")
    stored.write_bytes(b"not an array")
    fresh = Counting(occ, 2.0)
    np.testing.assert_array_equal(
        cached_distances(occ.occupied, 0.05, 2.0, str(tmp_path), fresh),
        obstacle_distances(occ, 2.0))
    assert fresh.calls == 1
    blocked = tmp_path / "a_file"
    blocked.write_text("")
    for cache_dir in (None, "", str(blocked / "below_a_file")):
        assert cached_distances(occ.occupied, 0.05, 2.0, cache_dir,
                                Counting(occ, 2.0)).shape == occ.occupied.shape
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
