"""Global planning (inflation + Dijkstra) and the DWA local planner."""
import math

import numpy as np
import pytest

from anyscale_nav_demo import costmap as cm
from anyscale_nav_demo.dwa import (DWAConfig, choose_velocity, rollout, rotate_in_place_rate,
                                   scan_obstacle_points, window_samples)

RES = 0.1


def grid_with_wall():
    """10 m x 6 m room; a wall across x = 5 m with a gap at the top (y 4..5.5 m)."""
    occ = np.zeros((60, 100), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    occ[:40, 50] = True
    return occ


def navfn(occ, goal):
    cost = cm.inflate(occ, np.zeros_like(occ), RES, 0.3, 0.8, 3.0)
    return cost, cm.NavigationFunction(cost, RES, (0.0, 0.0), cm.grid_graph(cost, RES, 0.0), goal)


def test_inflation_costs():
    occ = np.zeros((21, 21), dtype=bool)
    occ[10, 10] = True
    cost = cm.inflate(occ, np.zeros_like(occ), RES, 0.3, 1.0, 3.0)
    assert cost[10, 10] == cm.LETHAL
    assert cost[10, 12] == cm.INSCRIBED          # 0.2 m away: inside the robot's radius
    assert 0 < cost[10, 16] < cost[10, 14] < cm.INSCRIBED
    assert cost[0, 0] == 0                        # 1.41 m away: beyond the inflation radius


def test_dijkstra_finds_the_shortest_way_round_the_wall():
    occ = grid_with_wall()
    cost, nf = navfn(occ, (8.0, 1.0))
    path = nf.path_from((2.0, 1.0))
    assert path is not None
    assert np.hypot(*(path[0] - [2.0, 1.0])) < 0.15 and np.hypot(*(path[-1] - [8.0, 1.0])) < 0.15
    # it must pass through the gap, never through the wall or its inscribed zone
    assert path[:, 1].max() > 4.0
    r = ((path[:, 1]) / RES).astype(int)
    c = ((path[:, 0]) / RES).astype(int)
    assert np.all(cost[r, c] < cm.INSCRIBED)
    length = np.sum(np.hypot(*np.diff(path, axis=0).T))
    straight_via_gap = math.hypot(3.0, 3.4) * 2
    assert straight_via_gap - 0.5 < length < straight_via_gap * 1.15


def test_unreachable_goal_gives_no_path():
    occ = grid_with_wall()
    occ[40:, 50] = True                           # close the gap
    _, nf = navfn(occ, (8.0, 1.0))
    assert nf.path_from((2.0, 1.0)) is None


def test_cost_factor_keeps_path_off_walls():
    occ = np.zeros((30, 100), dtype=bool)
    occ[0, :] = occ[-1, :] = True                 # 3 m wide corridor
    cost = cm.inflate(occ, np.zeros_like(occ), RES, 0.3, 1.5, 2.0)
    g = cm.grid_graph(cost, RES, 5.0)
    nf = cm.NavigationFunction(cost, RES, (0, 0), g, (9.0, 0.6))
    path = nf.path_from((1.0, 0.6))
    assert path[len(path) // 2, 1] > 1.0          # swings to the middle on the way


def test_downsample_keeps_worst_cost():
    c = np.zeros((4, 4), dtype=np.uint8)
    c[1, 2] = 200
    assert cm.downsample_max(c, 2).tolist() == [[0, 200], [0, 0]]


def test_dynamic_window_respects_acceleration():
    cfg = DWAConfig(acc_lim_x=0.5, acc_lim_theta=1.0, control_period=0.1)
    v, w = window_samples(0.2, 0.0, cfg, 0.4, 1.0)
    assert v.min() == pytest.approx(0.15) and v.max() == pytest.approx(0.25)
    assert w.min() == pytest.approx(-0.1) and w.max() == pytest.approx(0.1)


def test_rollout_arc_geometry():
    x, y, th = rollout((0, 0, 0), np.array([1.0]), np.array([math.pi / 2]), 1.0, 0.5)
    assert (x[0, -1], y[0, -1], th[0, -1]) == pytest.approx((2 / math.pi, 2 / math.pi, math.pi / 2))


def open_costmap():
    occ = np.zeros((60, 100), dtype=bool)
    return (cm.inflate(occ, np.zeros_like(occ), RES, 0.3, 0.8, 3.0), RES, (0.0, 0.0))


def test_dwa_follows_a_straight_path():
    path = np.column_stack([np.linspace(1, 9, 80), np.full(80, 3.0)])
    v, w, ok = choose_velocity((1.0, 3.0, 0.0), (0.4, 0.0), path, open_costmap(), None, DWAConfig())
    assert ok and v > 0.3 and abs(w) < 0.2


def test_dwa_avoids_an_obstacle_the_map_does_not_have():
    path = np.column_stack([np.linspace(1, 9, 80), np.full(80, 3.0)])
    box = np.array([[x, y] for x in np.arange(1.6, 2.0, 0.05) for y in np.arange(2.7, 3.3, 0.05)])
    cfg = DWAConfig(control_period=1.0)            # a wide window: every speed is reachable
    free = choose_velocity((1.0, 3.0, 0.0), (0.2, 0.0), path, open_costmap(), None, cfg)
    v, w, ok = choose_velocity((1.0, 3.0, 0.0), (0.2, 0.0), path, open_costmap(), box, cfg)
    assert ok and free[2]
    x, y, _ = rollout((1.0, 3.0, 0.0), np.array([v]), np.array([w]), cfg.sim_time, 0.05)
    clear = np.min(np.hypot(x[0][:, None] - box[:, 0], y[0][:, None] - box[:, 1]))
    assert clear > cfg.robot_radius                # the chosen arc is collision free
    fx, fy, _ = rollout((1.0, 3.0, 0.0), np.array([free[0]]), np.array([free[1]]),
                        cfg.sim_time, 0.05)
    free_clear = np.min(np.hypot(fx[0][:, None] - box[:, 0], fy[0][:, None] - box[:, 1]))
    assert free_clear < cfg.robot_radius           # the arc chosen without the box hits it
    assert v > 0.0                                 # it keeps going, round the box or slower


def test_dwa_reports_failure_when_boxed_in():
    ring = np.array([[1 + 0.35 * math.cos(a), 3 + 0.35 * math.sin(a)]
                     for a in np.linspace(0, 6.28, 60)])
    path = np.column_stack([np.linspace(1, 9, 80), np.full(80, 3.0)])
    v, w, ok = choose_velocity((1.0, 3.0, 0.0), (0.2, 0.0), path, open_costmap(), ring, DWAConfig())
    assert not ok and v == 0.0 and w == 0.0


def test_scan_obstacle_points_keep_near_returns_in_the_map_frame():
    # Sensor at (1, 2) facing +y; beams every 45 degrees from -90 to +135 (sensor frame).
    ranges = [1.0, 5.0, 2.0, float("inf"), 0.01, 1.0]   # too far, no return, too near between
    pts = scan_obstacle_points((1.0, 2.0, math.pi / 2), ranges, -math.pi / 2, math.pi / 4, 0.05)
    # Kept: (1.0, -90 deg) -> (2, 2), (2.0, 0 deg) -> (1, 4), (1.0, 135 deg) -> 225 deg in the
    # map; every second of them stays.
    h = math.sqrt(0.5)
    assert np.allclose(pts, [[2.0, 2.0], [1.0 - h, 2.0 - h]])


def test_rotate_in_place_rate_is_proportional_within_its_limits():
    assert rotate_in_place_rate(0.03, 0.0, 1.0) == 0.0                 # close enough
    assert rotate_in_place_rate(0.1, 0.0, 1.0) == pytest.approx(0.2)   # at least 0.2 rad/s
    assert rotate_in_place_rate(0.0, 0.5, 1.0) == pytest.approx(-0.75)
    assert rotate_in_place_rate(2.0, 0.0, 1.0) == pytest.approx(1.0)   # at most max_w
    # The short way round across the +-pi seam: from 3.1 to -3.1 is +0.08 rad.
    assert rotate_in_place_rate(-3.1, 3.1, 1.0) == pytest.approx(0.2)
