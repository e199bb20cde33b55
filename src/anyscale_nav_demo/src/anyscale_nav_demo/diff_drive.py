"""Differential-drive kinematics: wheel speeds, exact arc integration, encoder dead reckoning."""
import math

import numpy as np

from .geometry import wrap_angle


def twist_to_wheel_speeds(v, w, wheel_radius, wheel_separation):
    """Left and right wheel angular speeds (rad/s) for a body twist (m/s, rad/s)."""
    return ((v - w * wheel_separation / 2.0) / wheel_radius,
            (v + w * wheel_separation / 2.0) / wheel_radius)


def wheel_arcs_to_motion(d_left, d_right, wheel_separation):
    """Distance travelled by the centre and heading change for wheel arc lengths (m)."""
    return (d_left + d_right) / 2.0, (d_right - d_left) / wheel_separation


def integrate_arc(pose, ds, dth):
    """Pose after moving ds along an arc that turns by dth (exact for constant curvature)."""
    x, y, th = pose
    if abs(dth) < 1e-9:
        return (x + ds * math.cos(th), y + ds * math.sin(th), th)
    r = ds / dth
    return (x + r * (math.sin(th + dth) - math.sin(th)),
            y - r * (math.cos(th + dth) - math.cos(th)),
            float(wrap_angle(th + dth)))


def limit_rate(current, target, max_step):
    """Move current towards target by at most max_step (an acceleration limit per tick)."""
    return current + max(-max_step, min(max_step, target - current))


class WheelOdometry:
    """Dead reckoning from cumulative wheel angles (rad), as sensor_msgs/JointState reports them."""

    def __init__(self, wheel_radius, wheel_separation, pose=(0.0, 0.0, 0.0)):
        self.r = wheel_radius
        self.b = wheel_separation
        self.pose = pose
        self.last = None
        self.v = 0.0
        self.w = 0.0

    def update(self, left_angle, right_angle, dt):
        """Integrate one encoder reading; returns the new pose. dt updates the velocity estimate."""
        if self.last is None:
            self.last = (left_angle, right_angle)
            return self.pose
        dl = (left_angle - self.last[0]) * self.r
        dr = (right_angle - self.last[1]) * self.r
        self.last = (left_angle, right_angle)
        ds, dth = wheel_arcs_to_motion(dl, dr, self.b)
        self.pose = integrate_arc(self.pose, ds, dth)
        if dt > 0:
            self.v, self.w = ds / dt, dth / dt
        return self.pose


class EncoderModel:
    """What wheel encoders report for true wheel rotations: slip noise, then tick quantisation.

    Drift comes from the true wheel radii differing from the nominal ones the odometry uses
    (set in the simulator) plus random slip proportional to each wheel's motion.
    """

    def __init__(self, ticks_per_rev=4096, slip_std=0.01, rng=None):
        self.ticks_per_rev = ticks_per_rev
        self.slip_std = slip_std
        self.rng = rng or np.random.default_rng()
        self.measured = np.zeros(2)   # wheel angles the encoder has counted (rad, unquantised)

    def advance(self, d_angles):
        """Add true wheel rotations (rad) with slip; returns the cumulative tick counts."""
        d = np.asarray(d_angles, dtype=float)
        self.measured += d * (1.0 + self.slip_std * self.rng.standard_normal(2))
        return np.floor(self.measured * self.ticks_per_rev / (2 * math.pi)).astype(np.int64)


def ticks_to_angles(ticks, ticks_per_rev):
    """Wheel angles (rad) from cumulative encoder ticks."""
    return np.asarray(ticks, dtype=float) * (2 * math.pi / ticks_per_rev)


def watchdog_target(target, age, timeout):
    """The motor controller's watchdog: a command older than timeout means stop."""
    return (0.0, 0.0) if age > timeout else target
