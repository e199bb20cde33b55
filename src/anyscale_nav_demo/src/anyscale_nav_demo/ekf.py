"""2-D extended Kalman filter fusing odometry twist and absolute (AMCL) poses, as in
robot_localization's ekf_localization_node with world_frame = map."""
import math

import numpy as np

from .geometry import compose, inverse, relative, wrap_angle

X, Y, YAW, V, W = range(5)


class PlanarEKF:
    """State [x, y, yaw, v, w] in the map frame; constant-velocity unicycle motion model."""

    def __init__(self, pose=(0.0, 0.0, 0.0), pose_cov=(0.25, 0.25, 0.07),
                 process_noise=(0.05, 0.05, 0.03, 0.25, 0.25), mahalanobis_threshold=np.inf):
        self.x = np.array([pose[0], pose[1], pose[2], 0.0, 0.0])
        self.P = np.diag(list(pose_cov) + [0.1, 0.1])
        self.q = np.asarray(process_noise, dtype=float)
        self.gate = mahalanobis_threshold

    def reset(self, pose, pose_cov):
        self.x[:3] = pose
        self.P[:3, :3] = np.diag(pose_cov)

    def predict(self, dt):
        """Propagate by dt seconds; process noise grows with dt (per-second variances)."""
        if dt <= 0:
            return
        x, y, th, v, w = self.x
        self.x[X] = x + v * math.cos(th) * dt
        self.x[Y] = y + v * math.sin(th) * dt
        self.x[YAW] = wrap_angle(th + w * dt)
        F = np.eye(5)
        F[X, YAW] = -v * math.sin(th) * dt
        F[X, V] = math.cos(th) * dt
        F[Y, YAW] = v * math.cos(th) * dt
        F[Y, V] = math.sin(th) * dt
        F[YAW, W] = dt
        self.P = F @ self.P @ F.T + np.diag(self.q * dt)

    def _update(self, z, H, R, angle_rows=()):
        innov = z - H @ self.x
        for i in angle_rows:
            innov[i] = wrap_angle(innov[i])
        S = H @ self.P @ H.T + R
        if self.gate < np.inf and float(innov @ np.linalg.solve(S, innov)) > self.gate ** 2:
            return False  # an outlier: robot_localization's *_rejection_threshold
        K = self.P @ H.T @ np.linalg.inv(S)
        self.x = self.x + K @ innov
        self.x[YAW] = wrap_angle(self.x[YAW])
        I_KH = np.eye(5) - K @ H
        self.P = I_KH @ self.P @ I_KH.T + K @ R @ K.T   # Joseph form: stays symmetric PSD
        return True

    def update_twist(self, v, w, var_v, var_w):
        """Body velocities from wheel odometry."""
        H = np.zeros((2, 5))
        H[0, V] = H[1, W] = 1.0
        return self._update(np.array([v, w]), H, np.diag([var_v, var_w]))

    def update_pose(self, pose, cov3):
        """Absolute map-frame pose (AMCL) with its 3x3 covariance (x, y, yaw)."""
        H = np.zeros((3, 5))
        H[0, X] = H[1, Y] = H[2, YAW] = 1.0
        R = np.asarray(cov3, dtype=float) + np.eye(3) * 1e-6
        return self._update(np.asarray(pose, dtype=float), H, R, angle_rows=(2,))

    @property
    def pose(self):
        return (float(self.x[X]), float(self.x[Y]), float(self.x[YAW]))

    def pose_after(self, dt):
        """The pose the motion model gives dt seconds from the state's time (dt < 0: before
        it), the state left as it is."""
        x, y, th, v, w = (float(c) for c in self.x)
        return (x + v * math.cos(th) * dt, y + v * math.sin(th) * dt, wrap_angle(th + w * dt))


def pose_now_from_delayed(measured_at_stamp, odom_at_stamp, odom_now):
    """Carry a pose measured at an earlier stamp forward by the odometry motion since then."""
    return compose(measured_at_stamp, relative(odom_at_stamp, odom_now))


def map_to_odom(map_to_base, odom_to_base):
    """The map->odom transform that makes map->odom->base_link equal the fused pose (REP 105)."""
    return compose(map_to_base, inverse(odom_to_base))
