"""Planar (x, y, yaw) pose algebra shared by the simulator, filters and planners."""
import math

import numpy as np


def wrap_angle(a):
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def compose(a, b):
    """Pose a (+) b: b expressed in a's frame, returned in a's parent frame."""
    ax, ay, at = a
    bx, by, bt = b
    c, s = math.cos(at), math.sin(at)
    return (ax + c * bx - s * by, ay + s * bx + c * by, float(wrap_angle(at + bt)))


def inverse(a):
    """Inverse of pose a, so that compose(a, inverse(a)) is the identity."""
    ax, ay, at = a
    c, s = math.cos(at), math.sin(at)
    return (-c * ax - s * ay, s * ax - c * ay, float(wrap_angle(-at)))


def relative(a, b):
    """Pose of b in a's frame (a^-1 (+) b): the motion from a to b."""
    return compose(inverse(a), b)


def yaw_to_quaternion(yaw):
    """(x, y, z, w) of a rotation by yaw about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def quaternion_to_yaw(x, y, z, w):
    """Yaw of a quaternion (roll and pitch ignored: the robot is planar)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
