"""EKF: prediction with the unicycle model, twist and pose updates, delayed-pose handling."""
import math

import numpy as np
import pytest

from anyscale_nav_demo.ekf import PlanarEKF, map_to_odom, pose_now_from_delayed
from anyscale_nav_demo.geometry import compose


def test_prediction_integrates_velocity_and_grows_covariance():
    f = PlanarEKF(pose=(0, 0, math.pi / 2))
    f.x[3], f.x[4] = 0.5, 0.0
    p0 = f.P[1, 1]
    f.predict(2.0)
    assert f.pose == pytest.approx((0.0, 1.0, math.pi / 2), abs=1e-9)
    assert f.P[1, 1] > p0


def test_twist_update_sets_velocity():
    f = PlanarEKF()
    for _ in range(20):
        f.update_twist(0.3, -0.1, 1e-4, 1e-4)
    assert f.x[3] == pytest.approx(0.3, abs=1e-3) and f.x[4] == pytest.approx(-0.1, abs=1e-3)


def test_pose_update_pulls_towards_measurement_by_relative_confidence():
    f = PlanarEKF(pose=(0, 0, 0), pose_cov=(1.0, 1.0, 1.0))
    f.update_pose((1.0, 0.0, 0.0), np.diag([1.0, 1.0, 1.0]))
    assert f.pose[0] == pytest.approx(0.5, abs=1e-6)      # equal confidence: half way
    f.update_pose((1.0, 0.0, 0.0), np.diag([1e-6, 1e-6, 1e-6]))
    assert f.pose[0] == pytest.approx(1.0, abs=1e-3)      # a sure measurement wins
    assert np.allclose(f.P, f.P.T)


def test_heading_innovation_wraps():
    f = PlanarEKF(pose=(0, 0, math.pi - 0.05), pose_cov=(1, 1, 1))
    f.update_pose((0, 0, -math.pi + 0.05), np.diag([1, 1, 1.0]))
    assert abs(abs(f.pose[2]) - math.pi) < 0.01           # meets across +-pi, not through 0


def test_outlier_gate_rejects_far_pose():
    f = PlanarEKF(pose=(0, 0, 0), pose_cov=(0.01, 0.01, 0.01), mahalanobis_threshold=5.0)
    assert not f.update_pose((5.0, 0.0, 0.0), np.diag([0.01, 0.01, 0.01]))
    assert f.pose[0] == 0.0


def test_fuses_drifting_odometry_with_absolute_poses():
    """Drive a circle: odometry twist 5 % fast, AMCL-like poses at 2 Hz with 5 cm noise."""
    rng = np.random.default_rng(0)
    f = PlanarEKF(pose=(0, 0, 0), pose_cov=(0.01, 0.01, 0.01))
    truth = (0.0, 0.0, 0.0)
    errs = []
    for k in range(400):                  # 40 s at 10 Hz
        truth = compose(truth, (0.03, 0.0, 0.01))        # v 0.3 m/s, w 0.1 rad/s
        f.predict(0.1)
        f.update_twist(0.315, 0.1, 0.01, 0.01)
        if k % 5 == 4:
            z = (truth[0] + rng.normal(0, 0.05), truth[1] + rng.normal(0, 0.05),
                 truth[2] + rng.normal(0, 0.02))
            f.update_pose(z, np.diag([0.0025, 0.0025, 0.0004]))
        errs.append(math.hypot(f.pose[0] - truth[0], f.pose[1] - truth[1]))
    assert np.sqrt(np.mean(np.square(errs[50:]))) < 0.08


def test_delayed_pose_carried_forward_and_map_to_odom():
    amcl_then = (2.0, 1.0, math.pi / 2)
    odom_then, odom_now = (5.0, 5.0, 0.0), (6.0, 5.0, 0.0)    # robot moved 1 m forward since
    now = pose_now_from_delayed(amcl_then, odom_then, odom_now)
    assert now == pytest.approx((2.0, 2.0, math.pi / 2), abs=1e-9)
    mo = map_to_odom(now, odom_now)
    assert compose(mo, odom_now) == pytest.approx(now, abs=1e-9)


def test_map_to_odom_pairs_poses_of_the_same_time_when_odometry_lags():
    # The robot drives +x at 0.5 m/s; the fused pose is at t = 10 s, the latest odometry pose
    # is from t = 9.6 s (late, a busy CPU). map->odom from the pose of 9.6 s: composing it with
    # odometry of any later time gives where the robot is then, not 0.2 m ahead of it.
    f = PlanarEKF(pose=(3.0, 1.0, 0.0))
    f.x[3] = 0.5
    at_odom = f.pose_after(-0.4)
    assert at_odom == pytest.approx((2.8, 1.0, 0.0), abs=1e-9)
    assert f.pose == (3.0, 1.0, 0.0)                         # the state is left as it is
    odom_at_9_6, odom_at_10 = (7.8, 2.0, 0.0), (8.0, 2.0, 0.0)
    mo = map_to_odom(at_odom, odom_at_9_6)
    assert compose(mo, odom_at_10) == pytest.approx((3.0, 1.0, 0.0), abs=1e-9)
    wrong = map_to_odom(f.pose, odom_at_9_6)                 # the lag's motion counted twice
    assert compose(wrong, odom_at_10)[0] == pytest.approx(3.2, abs=1e-9)
