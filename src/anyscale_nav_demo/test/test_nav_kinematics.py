"""Differential-drive kinematics, wheel odometry, encoders, the simulated body and the floor."""
import math

import numpy as np
import pytest

from anyscale_nav_demo.diff_drive import (EncoderModel, WheelOdometry, integrate_arc, limit_rate,
                                          ticks_to_angles, twist_to_wheel_speeds, watchdog_target)
from anyscale_nav_demo.floor_plan import make_loop_floor
from anyscale_nav_demo.geometry import compose, inverse, relative
from anyscale_nav_demo.goal_sequence import DONE, DRIVE, FACE_MARKER, WAIT_MARKER, GoalSequence


def test_pose_algebra():
    a, b = (1.0, 2.0, 0.5), (0.3, -0.2, 1.0)
    assert compose(a, inverse(a)) == pytest.approx((0, 0, 0), abs=1e-12)
    assert compose(a, relative(a, b)) == pytest.approx(b)


def test_wheel_speeds_and_arc():
    wl, wr = twist_to_wheel_speeds(0.0, 1.0, 0.05, 0.32)
    assert wl == pytest.approx(-3.2) and wr == pytest.approx(3.2)
    # a quarter circle of radius 1
    assert integrate_arc((0, 0, 0), math.pi / 2, math.pi / 2) == pytest.approx((1, 1, math.pi / 2))
    assert limit_rate(0.0, 1.0, 0.1) == pytest.approx(0.1)


def test_wheel_odometry_drives_a_square_exactly():
    odo = WheelOdometry(0.05, 0.32)
    left = right = 0.0
    odo.update(left, right, 0.0)
    for _ in range(4):
        left += 2.0 / 0.05
        right += 2.0 / 0.05
        odo.update(left, right, 1.0)                           # 2 m straight
        d = (math.pi / 2) * 0.16 / 0.05
        left, right = left - d, right + d
        odo.update(left, right, 1.0)                           # turn left 90 deg on the spot
    assert odo.pose == pytest.approx((0, 0, 0), abs=1e-9)


def test_encoder_quantises_and_slips():
    enc = EncoderModel(ticks_per_rev=100, slip_std=0.0, rng=np.random.default_rng(0))
    ticks = enc.advance([2 * math.pi * 1.004, 0.0])
    assert ticks.tolist() == [100, 0]
    assert ticks_to_angles(ticks, 100)[0] == pytest.approx(2 * math.pi)
    slips = [EncoderModel(4096, 0.05, np.random.default_rng(s)).advance([10.0, 10.0])
             for s in range(20)]
    counted = np.array(slips, dtype=float) / 4096 * 2 * math.pi
    assert counted.std() == pytest.approx(0.5, rel=0.4)      # 5 % of 10 rad, per wheel


def test_watchdog_stops_stale_commands():
    assert watchdog_target((0.3, 0.1), 0.2, 0.5) == (0.3, 0.1)
    assert watchdog_target((0.3, 0.1), 0.6, 0.5) == (0.0, 0.0)


def test_office_floor_loop_is_115_m_and_goals_are_free():
    plan = make_loop_floor()
    side = plan.goals[1][0] - plan.start[1]              # c1 - c0: the centre line's side
    assert 4 * side == pytest.approx(115.0)
    m = plan.map
    for gx, gy, _, _ in plan.goals:
        c, r = m.world_to_cell(gx, gy)
        assert m.free[r, c]
    assert [mk["id"] for mk in plan.markers] == [0, 1, 2, 3]
    for mk in plan.markers:                              # each marker sits on a wall face
        c, r = m.world_to_cell(mk["x"] - 0.05 * math.cos(mk["yaw"]),
                               mk["y"] - 0.05 * math.sin(mk["yaw"]))
        assert m.occupied[r, c]


def test_goal_sequence_waits_for_markers():
    seq = GoalSequence([(1.0, 0.0, math.pi / 2, 7), (2.0, 0.0, 0.0, -1)], 0.2, 0.1, 3.0)
    assert seq.step((0.0, 0.0, 0.0), 0.0) == DRIVE
    assert seq.step((1.0, 0.0, 0.0), 1.0) == FACE_MARKER         # at the goal, marker unseen
    assert seq.step((1.0, 0.0, math.pi / 2), 2.0) == WAIT_MARKER
    seq.marker_seen(7)
    assert seq.step((1.0, 0.0, math.pi / 2), 2.5) == DRIVE and seq.index == 1
    assert seq.step((2.0, 0.05, 0.0), 3.0) == DONE
    # a marker seen on the way needs no stop; one never seen is given up after the timeout
    seq = GoalSequence([(1.0, 0.0, 0.0, 4), (2.0, 0.0, 0.0, 5)], 0.2, 0.1, 3.0)
    seq.marker_seen(4)
    assert seq.step((1.0, 0.0, 1.0), 0.0) == DRIVE and seq.index == 1
    seq.step((2.0, 0.0, 0.0), 1.0)
    assert seq.step((2.0, 0.0, 0.0), 5.0) == DONE and seq.missed == [5]
