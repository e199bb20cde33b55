"""Ray casting against hand-made grids: exact wall distances, corners, max range, noise model."""
import math

import numpy as np
import pytest

from anyscale_nav_demo import laser_model
from anyscale_nav_demo.raycast import cast_rays


@pytest.fixture
def box():
    """10 m x 10 m room (0.05 m cells), walls one cell thick on every side."""
    g = np.zeros((200, 200), dtype=bool)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    return g


def test_axis_aligned_walls(box):
    r = cast_rays(box, 0.05, (0.0, 0.0), 3.0, 4.0, [0, math.pi / 2, math.pi, -math.pi / 2], 20.0)
    # walls' inner faces are at x = 0.05, x = 9.95, y = 0.05, y = 9.95
    assert r == pytest.approx([6.95, 5.95, 2.95, 3.95], abs=1e-9)


def test_diagonal_matches_geometry(box):
    r = cast_rays(box, 0.05, (0.0, 0.0), 5.0, 5.0, [math.pi / 4], 20.0)[0]
    assert r == pytest.approx(4.95 * math.sqrt(2), abs=1e-6)


def test_max_range_gives_inf(box):
    r = cast_rays(box, 0.05, (0.0, 0.0), 5.0, 5.0, [0.0, 1.0], 2.0)
    assert np.all(np.isinf(r))


def test_ray_cannot_slip_through_a_diagonal_corner():
    g = np.zeros((20, 20), dtype=bool)
    g[10, 10] = g[11, 11] = True    # two cells touching only at a corner
    r = cast_rays(g, 1.0, (0.0, 0.0), 10.5, 11.5, [-math.pi / 4], 30.0)[0]
    # from (10.5, 11.5) heading down-right the ray meets the corner point (11, 11)
    assert r == pytest.approx(math.sqrt(0.5), abs=1e-6)


def test_obstacle_in_front_shadows_wall(box):
    box = box.copy()
    box[80, 100] = True                                  # cell at x 5.0..5.05, y 4.0..4.05
    r = cast_rays(box, 0.05, (0.0, 0.0), 2.0, 4.025, [0.0], 20.0)[0]
    assert r == pytest.approx(3.0, abs=1e-9)


def test_urg_conversions_round_trip():
    rng = np.random.default_rng(3)
    true = np.array([0.5, 2.0, 5.0, np.inf, 7.0, 0.01])
    raw = laser_model.ranges_to_raw_mm(true)
    assert raw.tolist() == [500, 2000, 5000, 0, 0, 0]     # no echo / out of range -> error code
    back = laser_model.raw_mm_to_ranges(raw)
    assert back[:3] == pytest.approx([0.5, 2.0, 5.0])
    assert np.all(np.isinf(back[3:]))
    noisy = laser_model.noisy_ranges(np.full(20000, 3.0), rng)
    assert np.std(noisy) == pytest.approx(0.03, rel=0.05)  # 1 % at 3 m
