"""Shared rospy plumbing for the nodes: validated params, clean fatal exits, message conversions.

Only nodes import this module; the algorithm modules stay free of ROS.
"""
import sys

import rospy
from geometry_msgs.msg import Pose, PoseWithCovariance, Quaternion, TransformStamped

from anyscale_core.param_spec import REQUIRED, Param, ParamError  # noqa: F401 (re-exported)

from .geometry import quaternion_to_yaw, yaw_to_quaternion
from .occupancy_map import MapError


_MISSING = object()
_private_params = None      # the node's private namespace, read from the master once


def _lookup(name):
    """A parameter's value, or _MISSING. The private ones (~name) come from one read of the
    node's whole private namespace: nodes read their parameters as they start, and a node
    brought home to a starved robot waits for the scheduler after every XML-RPC reply, so one
    call instead of one per parameter shortens its start."""
    global _private_params
    if not name.startswith("~"):
        return rospy.get_param(name, _MISSING)
    if _private_params is None:
        _private_params = rospy.get_param("~", {})
    value = _private_params
    for part in name[1:].strip("/").split("/"):
        if not isinstance(value, dict) or part not in value:
            return _MISSING
        value = value[part]
    return value


def raw_param(name, default):
    """A parameter as the master holds it (lists, dicts), for the node to check itself."""
    value = _lookup(name)
    return default if value is _MISSING else value


_KINDS = {float: "float", int: "int", str: "text", bool: "bool"}


def param(name, default=REQUIRED, kind=float, **bounds):
    """A parameter of type `kind` checked by param_spec.Param (minimum=, maximum=, above=);
    ParamError names it by its resolved name."""
    spec = Param(rospy.resolve_name(name), default, "", kind=_KINDS.get(kind, kind), **bounds)
    return spec.read(lambda _, fallback: raw_param(name, fallback), prefix="")


def flag(name, default):
    """A true/false parameter; anything else (the string "false", 0) is refused by name."""
    return param(name, default, bool)


def positive(name, default, kind=float):
    return param(name, default, kind, minimum=0, above=True)


def non_negative(name, default, kind=float):
    return param(name, default, kind, minimum=0)


def run_node(name, build, anonymous=False):
    """init_node, build the node (which may raise ParamError or a file error), spin.

    Expected configuration errors end the process with one clear log line and exit code 1,
    no traceback (that is what a user who mistyped a map path should see).
    """
    rospy.init_node(name, anonymous=anonymous)
    try:
        node = build()
    except (ParamError, MapError, ValueError, OSError) as e:
        rospy.logfatal("%s: %s", rospy.get_name(), e)
        rospy.signal_shutdown(str(e))
        sys.exit(1)
    try:
        rospy.spin()
    except rospy.ROSInterruptException:
        pass
    return node


def pose_msg(x, y, yaw):
    q = yaw_to_quaternion(yaw)
    p = Pose()
    p.position.x, p.position.y = x, y
    p.orientation = Quaternion(*q)
    return p


def pose_from_msg(p):
    o = p.orientation
    return (p.position.x, p.position.y, quaternion_to_yaw(o.x, o.y, o.z, o.w))


def pose_cov_msg(x, y, yaw, cov3):
    """PoseWithCovariance from a planar pose and its 3x3 (x, y, yaw) covariance."""
    m = PoseWithCovariance()
    m.pose = pose_msg(x, y, yaw)
    c = [0.0] * 36
    idx = (0, 1, 5)
    for i in range(3):
        for j in range(3):
            c[idx[i] * 6 + idx[j]] = float(cov3[i][j])
    m.covariance = c
    return m


def cov3_from_msg(cov36):
    idx = (0, 1, 5)
    return [[cov36[i * 6 + j] for j in idx] for i in idx]


def transform_msg(parent, child, x, y, yaw, stamp, z=0.0):
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = x, y, z
    t.transform.rotation = Quaternion(*yaw_to_quaternion(yaw))
    return t


def planar_from_transform(t):
    """(x, y, yaw) of a geometry_msgs/Transform."""
    r = t.rotation
    return (t.translation.x, t.translation.y, quaternion_to_yaw(r.x, r.y, r.z, r.w))


def mount_transform(parent, child, mount, stamp):
    """Static transform of a sensor mount dict {x, y, z, yaw, [pitch]} on the robot."""
    t = transform_msg(parent, child, float(mount.get("x", 0)), float(mount.get("y", 0)),
                      float(mount.get("yaw", 0)), stamp, float(mount.get("z", 0)))
    return t


def optical_transform(parent, child, stamp):
    """camera_link (x forward, z up) -> optical frame (z forward, x right, y down), REP 103."""
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.rotation = Quaternion(-0.5, 0.5, -0.5, 0.5)
    return t


def occupancy_map_from_msg(msg):
    """OccupancyMap of a nav_msgs/OccupancyGrid."""
    import numpy as np
    from .occupancy_map import OccupancyMap
    data = np.asarray(msg.data, dtype=np.int8).reshape(msg.info.height, msg.info.width)
    return OccupancyMap(data, msg.info.resolution, pose_from_msg(msg.info.origin))
