"""The decision node's link map and forecast in rospy terms: the robot's pose (tf or a pose
topic), the planner's path, each remote scale's link from its ScaleStatus at the pose of the
status's stamp, the map loaded from ~link_map_file and saved there, and shown in rviz. The grid
and the forecast themselves are link_map.py and link_forecast.py."""
import math
import threading
import time
from typing import Dict, List, Optional, Sequence

import genpy
import roslib.message
import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from nav_msgs.msg import Path
from visualization_msgs.msg import Marker, MarkerArray

from .job_worker import JobWorker
from .link_anticipation import NOTHING_DONE, Anticipation
from .link_forecast import LinkForecast, LinkForecastParams, PathTracker, PoseTrack, forecast_links
from .link_map import LinkMap, LinkMapError, load_link_map, write_link_map

# A pose older than this is no pose: the forecast is off until a new one comes.
POSE_STALE_S = 1.0
MARKERS_PERIOD_S = 5.0
POSE_TYPES = ("nav_msgs/Odometry", "geometry_msgs/PoseStamped",
              "geometry_msgs/PoseWithCovarianceStamped")


class LinkForecastRos:
    """Thread-safe: statuses, poses and paths come on rospy's threads, the ticks on another."""

    def __init__(self, params: LinkForecastParams, remote_scales: Sequence[str],
                 full_scale_mbps: float):
        self.p = params
        self.scales = list(remote_scales)
        self.full_scale_mbps = max(full_scale_mbps, 1e-3)
        self.lock = threading.Lock()
        self.map = self._load()
        self.poses = PoseTrack(params.speed_window_s, params.cruise_window_s)
        self.path = PathTracker(params.max_offset_m)
        self.heard: set = set()                 # remote scales whose status came at least once
        self.live: Dict[str, float] = {}        # remote scale -> its latest measured Mbit/s
        self.why_none = ""                      # why the latest tick had no forecast
        self.logged = set()                     # "none", "available": each said once
        self.latest: Optional[Dict[str, LinkForecast]] = None
        self.changed = False
        self.markers_at = -math.inf
        self.saver = JobWorker("anyscale_link_map", on_error=lambda e, _: rospy.logwarn(
            "anyscale decision: cannot save the link map to %s: %s", params.map_file, e))
        self.saved_at = time.monotonic()
        self.tf_buffer = None
        if params.pose_topic:
            rospy.Subscriber(params.pose_topic, rospy.AnyMsg, self._on_pose, queue_size=5)
        else:
            self.tf_buffer = tf2_ros.Buffer(rospy.Duration(10.0))
            self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        if params.path_topic:
            rospy.Subscriber(params.path_topic, Path, self._on_path, queue_size=1)
        self.marker_pub = rospy.Publisher("~link_map", MarkerArray, queue_size=1, latch=True)

    def _load(self) -> LinkMap:
        empty = LinkMap(self.p.map, self.p.map_frame)
        if not self.p.map_file:
            rospy.loginfo("anyscale decision: link map learned in memory only (~link_map_file "
                          "not set)")
            return empty
        try:
            link_map = load_link_map(self.p.map_file, self.p.map, self.p.map_frame, time.time())
        except LinkMapError as e:
            rospy.logwarn("anyscale decision: link map %s; starting with an empty one (the "
                          "reactive rules until it is learned), saved there", e)
            return empty
        rospy.loginfo("anyscale decision: link map %s: %d observations of %s", self.p.map_file,
                      link_map.observation_count(), ", ".join(link_map.scales()) or "no scale")
        return link_map

    # --- inputs -------------------------------------------------------------------------------
    def _on_pose(self, msg):
        kind = msg._connection_header.get("type", "")
        if kind not in POSE_TYPES:
            rospy.logwarn_once("anyscale decision: ~pose_topic %s is a %s; expected one of %s",
                               self.p.pose_topic, kind, ", ".join(POSE_TYPES))
            return
        try:
            pose = roslib.message.get_message_class(kind)().deserialize(msg._buff)
        except genpy.DeserializationError:
            return
        if pose.header.frame_id.lstrip("/") != self.p.map_frame:
            rospy.logwarn_once("anyscale decision: ~pose_topic %s is in frame %s, not %s: no "
                               "link forecast from it", self.p.pose_topic,
                               pose.header.frame_id, self.p.map_frame)
            return
        position = pose.pose.pose.position if kind != POSE_TYPES[1] else pose.pose.position
        with self.lock:
            self.poses.add(pose.header.stamp.to_sec(), position.x, position.y)

    def _on_path(self, msg):
        if msg.poses and msg.header.frame_id.lstrip("/") != self.p.map_frame:
            rospy.logwarn_once("anyscale decision: the path on %s is in frame %s, not %s: no "
                               "link forecast from it", self.p.path_topic, msg.header.frame_id,
                               self.p.map_frame)
            return
        points = [(p.pose.position.x, p.pose.position.y) for p in msg.poses]
        with self.lock:
            self.path.set_path(points)

    def observe_status(self, msg):
        """A remote scale's link as its status measured it, where the robot was at its stamp.
        Lost is link.up false (its latest probe unanswered); loss_ratio is not used: a share
        over the recent probes, it would carry a hole on past its end."""
        if msg.is_master or msg.scale not in self.scales:
            return
        lost = not msg.link.up
        mbps = 0.0 if lost else float(msg.link.bandwidth_mbps)
        stamp = msg.header.stamp.to_sec() if not msg.header.stamp.is_zero() \
            else rospy.get_time()
        with self.lock:
            self.heard.add(msg.scale)
            self.live[msg.scale] = mbps if math.isfinite(mbps) else math.nan
            where = self.poses.at(stamp)
            if where is None or not (lost or math.isfinite(mbps)):
                return
            self.map.add(msg.scale, time.time(), where[0], where[1], mbps, lost)
            self.changed = True

    def observe_links(self, link_up: Dict[str, bool]):
        """After a tick: each remote scale the engine found out of reach (its status silent,
        the uplink without carrier) is a loss where the robot is now, once it was heard."""
        with self.lock:
            pose = self._fresh_pose()
            for scale, up in link_up.items():
                if not up and scale in self.heard:
                    self.live[scale] = 0.0
                    if pose is not None:
                        self.map.add(scale, time.time(), pose[0], pose[1], math.nan, True)
                        self.changed = True

    # --- the forecast -------------------------------------------------------------------------
    def forecasts(self) -> Optional[Dict[str, LinkForecast]]:
        """Per remote scale, the link over the horizon; None without path, pose or map (the
        log says so once, and once when a forecast is first there)."""
        self._poll_tf()
        with self.lock:
            pose = self._fresh_pose()
            out, why = None, ""
            if not self.p.path_topic:
                why = "no ~path_topic"
            elif not self.path.has_path:
                why = f"no path on {self.p.path_topic} yet"
            elif pose is None:
                why = "no pose of the robot " + (f"on {self.p.pose_topic}" if self.p.pose_topic
                                                 else f"from tf {self.p.map_frame} -> "
                                                      f"{self.p.base_frame}")
            elif not self.map.scales():
                why = "the link map is empty"
            else:
                out = forecast_links(self.map, self.scales, self.path, pose[0], pose[1],
                                     self.poses.cruise_speed(), self.p.horizon_s)
                if out is None:
                    why = f"the robot is over {self.p.max_offset_m:g} m off its path"
            self.latest, self.why_none = out, why
        self._log_once(why)
        self._publish_markers()
        self._save_every_period()
        return out

    def _log_once(self, why: str):
        state = "available" if not why else "none"
        if state in self.logged:
            return
        self.logged.add(state)
        if why:
            rospy.loginfo("anyscale decision: no link forecast (%s): the reactive rules decide",
                          why)
        elif self.p.enabled:
            rospy.loginfo("anyscale decision: link forecast available (path on %s, pose from "
                          "%s): moves out early, planned returns before a hole",
                          self.p.path_topic, self.p.pose_topic or "tf")
        else:
            rospy.loginfo("anyscale decision: link forecast available, not used (~link_forecast "
                          "false): the reactive rules decide; the map is still learned")

    def diagnose(self, stat, last: Anticipation, node_names: Sequence[str]):
        """/diagnostics "link ahead": what the forecast made the engine do at its latest tick,
        and per remote scale the link ahead in words (`anyscale top` shows them)."""
        done = [f"{node_names[i]} out early ({s:.0f} s carried)" for i, s in last.cleared.items()]
        done += [f"{node_names[i]} home: {why}" for i, why in last.home.items()]
        done += [f"{node_names[i]} held: {why}" for i, why in last.held.items()]
        used = "" if self.p.enabled else " (not used: ~link_forecast false)"
        stat.summary(DiagnosticStatus.OK, ("; ".join(done) or NOTHING_DONE) + used)
        for scale, line in self.describe().items():
            stat.add(scale, line)
        return stat

    def describe(self) -> Dict[str, str]:
        """Per remote scale, the forecast in words (or why there is none), for /diagnostics."""
        with self.lock:
            if self.latest is None:
                return {s: f"no forecast: {self.why_none or 'not yet'}" for s in self.scales}
            return {s: fc.describe(self.live.get(s, math.nan))
                    for s, fc in sorted(self.latest.items())}

    def _fresh_pose(self):
        latest = self.poses.latest()
        if latest is None or rospy.get_time() - latest[0] > POSE_STALE_S:
            return None
        return latest[1:]

    def _poll_tf(self):
        if self.tf_buffer is None:
            return
        try:
            t = self.tf_buffer.lookup_transform(self.p.map_frame, self.p.base_frame,
                                                rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException):
            return
        with self.lock:
            self.poses.add(t.header.stamp.to_sec(), t.transform.translation.x,
                           t.transform.translation.y)

    # --- the file and rviz --------------------------------------------------------------------
    def _save_every_period(self):
        if not self.p.map_file or time.monotonic() - self.saved_at < self.p.save_period_s:
            return
        self.saved_at = time.monotonic()
        data = self._data()
        self.saver.submit(lambda: write_link_map(data, self.p.map_file), key="save")

    def save(self):
        """At shutdown: the map written now, in this thread."""
        if not self.p.map_file:
            return
        try:
            write_link_map(self._data(), self.p.map_file)
            rospy.loginfo("anyscale decision: link map saved to %s", self.p.map_file)
        except OSError as e:
            rospy.logwarn("anyscale decision: cannot save the link map to %s: %s",
                          self.p.map_file, e)

    def _data(self) -> dict:
        with self.lock:
            self.map.age_out(time.time())
            return self.map.to_dict()

    def _publish_markers(self):
        if time.monotonic() - self.markers_at < MARKERS_PERIOD_S:
            return
        with self.lock:
            if not self.changed and self.markers_at > -math.inf:
                return
            self.changed = False
            msg = self._markers()
        self.markers_at = time.monotonic()
        self.marker_pub.publish(msg)

    def _markers(self) -> MarkerArray:
        """A CUBE_LIST per remote scale: each known cell from red (its figure 0 or its link
        mostly lost) to green (full_scale_mbps and more), the scales stacked 10 cm apart."""
        markers: List[Marker] = []
        r = self.p.map.resolution_m
        for k, scale in enumerate(self.scales):
            m = Marker(ns=f"link_map/{scale}", id=0, type=Marker.CUBE_LIST, action=Marker.ADD)
            m.header.frame_id, m.header.stamp = self.p.map_frame, rospy.Time.now()
            m.pose.orientation.w = 1.0
            m.scale.x = m.scale.y = 0.9 * r
            m.scale.z = 0.05
            for cell, stats in self.map.known_cells(scale):
                x, y = self.map.centre_of(cell)
                m.points.append(Point(x, y, 0.05 + 0.1 * k))
                good = 0.0 if stats.lost_fraction > self.p.map.hole_lost_fraction else \
                    min(stats.low_mbps / self.full_scale_mbps, 1.0)
                m.colors.append(ColorRGBA(1.0 - good, good, 0.0, 0.6))
            if not m.points:
                m.action = Marker.DELETE
            markers.append(m)
        return MarkerArray(markers=markers)
