"""The configuration path node's ROS side (the paper's Fig. 5 in rviz): the robot's pose from
tf, coloured by /anyscale/mapping, published as a latched MarkerArray on
/anyscale/configuration_path. The accounting is configuration_path.py (no ROS)."""
import threading

import rospy
import tf2_ros
from anyscale_msgs.msg import Mapping as MappingMsg
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from .configuration_path import (ConfigurationColours, PathAccumulator, configuration_name,
                                 configuration_of, format_totals)
from .param_spec import Param, ParamError, read_all

PATH_NS = "configuration_path"
LEGEND_NS = "configuration_legend"
LEGEND_TEXT_M = 0.9       # legend text height: about 18 px at the demo view's 20 px/m
LEGEND_SPACING_M = 1.0

PARAMS = (
    Param("global_frame", "map", "fixed frame the path is drawn in", kind="frame"),
    Param("base_frame", "base_link", "the robot's base frame", kind="frame"),
    Param("master_scale", "robot", "the master scale: a configuration names what is off it",
          kind="str"),
    Param("rate_hz", 4.0, "pose samples per second", "Hz", minimum=0.1),
    # Not faster than 1 Hz: the array carries the whole path (up to max_points).
    Param("publish_period_s", 1.0, "at most one MarkerArray per period", "s", minimum=1.0),
    Param("min_step_m", 0.05, "a sample closer than this to the last one is dropped", "m",
          minimum=0.0),
    Param("max_points", 20000, "points kept; the oldest go first", minimum=2),
    Param("line_width_m", 0.08, "width of the path's lines", "m", minimum=0.001),
    # rviz centres the text on (legend_x, legend_y): near the map origin, inside the demo view.
    Param("legend_x", 8.0, "legend position in global_frame", "m"),
    Param("legend_y", 6.0, "legend position in global_frame (first line)", "m"),
)


def read_params(get=None):
    """The node's parameters, checked (ParamError names a bad one)."""
    p = read_all(PARAMS, get or rospy.get_param)
    p["master"] = p.pop("master_scale")
    return p


def base_marker(frame, ns, marker_id, kind):
    m = Marker()
    m.header.frame_id = frame
    m.ns, m.id, m.type, m.action = ns, marker_id, kind, Marker.ADD
    m.pose.orientation.w = 1.0   # rviz warns about an all-zero quaternion
    return m


def segment_marker(frame, marker_id, segment, colour, width):
    m = base_marker(frame, PATH_NS, marker_id, Marker.LINE_STRIP)
    m.scale.x = width
    m.color.r, m.color.g, m.color.b, m.color.a = colour
    m.points = [Point(x, y, 0.02) for x, y in segment.points]   # just above the map
    return m


def legend_marker(frame, marker_id, x, y, text, colour):
    m = base_marker(frame, LEGEND_NS, marker_id, Marker.TEXT_VIEW_FACING)
    m.pose.position.x, m.pose.position.y, m.pose.position.z = x, y, 0.1
    m.scale.z = LEGEND_TEXT_M
    m.color.r, m.color.g, m.color.b, m.color.a = colour
    m.text = text
    return m


def delete_marker(frame, ns, marker_id):
    m = base_marker(frame, ns, marker_id, Marker.LINE_STRIP)
    m.action = Marker.DELETE
    return m


class ConfigurationPathNode:
    def __init__(self, p):
        self.p = p
        self.path = PathAccumulator(p["min_step_m"], p["max_points"])
        self.colours = ConfigurationColours()
        self.lock = threading.Lock()
        self.config = None            # no sample is recorded before the first mapping
        self.changed = False
        self.published_segments = 0   # marker ids above the current count must be deleted
        self.buffer = tf2_ros.Buffer()
        self.listener = tf2_ros.TransformListener(self.buffer)
        self.pub = rospy.Publisher("/anyscale/configuration_path", MarkerArray, queue_size=1,
                                   latch=True)
        rospy.Subscriber("/anyscale/mapping", MappingMsg, self.on_mapping, queue_size=5)
        rospy.Timer(rospy.Duration(1.0 / p["rate_hz"]), self.on_sample)
        rospy.Timer(rospy.Duration(p["publish_period_s"]), self.on_publish)
        rospy.on_shutdown(self.log_totals)

    def on_mapping(self, msg):
        mapping = {a.node: a.scale for a in msg.assignments}
        if mapping and self.p["master"] not in mapping.values():
            rospy.logwarn_once("configuration_path: no node runs on ~master_scale '%s' "
                               "(scales: %s); is the parameter right?", self.p["master"],
                               ", ".join(sorted(set(mapping.values()))))
        config = configuration_of(mapping, self.p["master"])
        with self.lock:
            if config == self.config:
                return
            previous, self.config = self.config, config
            self.colours.colour(config)   # claim a colour now: palette order = order of first use
            self.changed = True
            distance = self.path.distance_m()
        rospy.loginfo("configuration_path: %s%s after %.1f m",
                      configuration_name(config, self.p["master"]),
                      "" if previous is None
                      else f" (was {configuration_name(previous, self.p['master'])})",
                      distance)

    def on_sample(self, _event):
        with self.lock:
            config = self.config
        if config is None:
            rospy.loginfo_throttle(30.0, "configuration_path: waiting for /anyscale/mapping")
            return
        try:
            tf = self.buffer.lookup_transform(self.p["global_frame"], self.p["base_frame"],
                                              rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException) as e:
            rospy.logwarn_throttle(10.0, "configuration_path: no transform %s -> %s: %s",
                                   self.p["global_frame"], self.p["base_frame"], e)
            return
        t = tf.transform.translation
        with self.lock:
            if self.path.add(rospy.get_time(), t.x, t.y, config):
                self.changed = True

    def on_publish(self, _event):
        with self.lock:
            if not self.changed:
                return   # nothing new: the latched array is still current
            self.changed = False
            segments = self.path.segments()
            totals = self.path.totals()
        frame, markers = self.p["global_frame"], MarkerArray()
        drawable = [s for s in segments if len(s.points) >= 2]   # rviz rejects 1-point strips
        for i, segment in enumerate(drawable):
            markers.markers.append(segment_marker(frame, i, segment,
                                                  self.colours.colour(segment.config),
                                                  self.p["line_width_m"]))
        for i in range(len(drawable), self.published_segments):
            markers.markers.append(delete_marker(frame, PATH_NS, i))
        self.published_segments = len(drawable)
        for i, (config, total) in enumerate(totals.items()):
            text = f"{configuration_name(config, self.p['master'])}  {total.distance_m:.1f} m"
            markers.markers.append(legend_marker(frame, i, self.p["legend_x"],
                                                 self.p["legend_y"] - i * LEGEND_SPACING_M,
                                                 text, self.colours.colour(config)))
        self.pub.publish(markers)

    def log_totals(self):
        with self.lock:
            totals = self.path.totals()
        if totals:
            rospy.loginfo("configuration_path: distance and time per configuration\n%s",
                          format_totals(totals, self.p["master"]))


def main():
    rospy.init_node("configuration_path")
    try:
        ConfigurationPathNode(read_params())
    except (ParamError, ValueError) as e:
        rospy.logfatal("configuration_path: %s", e)
        return 1
    rospy.spin()
    return 0
