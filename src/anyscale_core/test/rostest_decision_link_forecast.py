#!/usr/bin/python3
"""rostest: the decision node's link map and forecast as ROS wires them (link_forecast_ros.py).
A robot driven to and fro along a line (a PoseStamped in the map frame) with its plan (a
nav_msgs/Path) ahead of it: the map learns the laptop's link there from the agents' status, is
shown on ~link_map, forecasts the link ahead on /diagnostics, is saved to ~link_map_file every
period and at shutdown; a corrupt file there at start is one warning and an empty map."""
import math
import os
import signal
import subprocess
import tempfile
import threading
import time
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from visualization_msgs.msg import MarkerArray

from anyscale_core.link_map import LinkMapError, LinkMapParams, load_link_map
from anyscale_core.polling import wait_for

SPEED_MPS = 0.5
LENGTH_M = 6.0


def executable(name):
    from catkin.find_in_workspaces import find_in_workspaces
    return find_in_workspaces(["libexec"], project="anyscale_core", path=name,
                              first_matching_workspace_only=True)[0]


def stamped(x, y, stamp):
    p = PoseStamped()
    p.header.frame_id, p.header.stamp = "map", stamp
    p.pose.position.x, p.pose.position.y = x, y
    p.pose.orientation.w = 1.0
    return p


def saved_cells(path):
    """The laptop's known cells in the map file (none while it is the corrupt one)."""
    try:
        return list(load_link_map(path, LinkMapParams(min_observations=2))
                    .known_cells("laptop"))
    except LinkMapError:
        return []


class Robot(threading.Thread):
    """To and fro along y = 0.5 from x = 0 to LENGTH_M: its pose at 10 Hz, its plan (to the
    end it drives to, then back) at 1 Hz."""

    def __init__(self):
        super().__init__(daemon=True)
        self.running = True
        self.pose_pub = rospy.Publisher("/test_pose", PoseStamped, queue_size=5)
        self.path_pub = rospy.Publisher("/test_plan", Path, queue_size=1, latch=True)

    def run(self):
        start, k = time.monotonic(), 0
        while self.running and not rospy.is_shutdown():
            d = (time.monotonic() - start) * SPEED_MPS % (2 * LENGTH_M)
            forward = d < LENGTH_M
            x = d if forward else 2 * LENGTH_M - d
            now = rospy.Time.now()
            self.pose_pub.publish(stamped(x, 0.5, now))
            if k % 10 == 0:
                ahead = [LENGTH_M, 0.0] if forward else [0.0, LENGTH_M]
                points = [x] + [ahead[0] + (ahead[1] - ahead[0]) * j / 12 for j in range(13)]
                path = Path()
                path.header.frame_id, path.header.stamp = "map", now
                path.poses = [stamped(px, 0.5, now) for px in points]
                self.path_pub.publish(path)
            k += 1
            time.sleep(0.1)


class DecisionLinkForecastTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("decision_link_forecast_test")
        cls.model = rospy.get_param("~model")

    def test_the_map_is_learned_shown_forecast_and_saved(self):
        tmp = tempfile.mkdtemp(prefix="anyscale_link_map_")
        map_file = os.path.join(tmp, "link_map.yaml")
        with open(map_file, "w") as f:
            f.write("format: anyscale_link_map\nversion: 7\n")     # corrupt: a later version
        markers, ahead = [], []
        rospy.Subscriber("/anyscale_decision/link_map", MarkerArray, markers.append)
        rospy.Subscriber("/diagnostics", DiagnosticArray, lambda m: ahead.extend(
            s for s in m.status if s.name == "anyscale_decision: link ahead"))
        robot = Robot()
        robot.start()
        self.addCleanup(setattr, robot, "running", False)
        decision = subprocess.Popen(
            [executable("decision_node"), "__name:=anyscale_decision", "_model:=" + self.model,
             "_period_s:=0.5", "_adopt_wait_s:=3.0", "_path_topic:=/test_plan",
             "_pose_topic:=/test_pose", "_link_map_file:=" + map_file,
             "_link_map_save_period_s:=2.0", "_link_map_min_observations:=2"],
            start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        lines = []
        reader = threading.Thread(target=lambda: lines.extend(decision.stdout), daemon=True)
        reader.start()
        try:
            def laptop_cells():
                return max([len(m.points) for a in markers for m in a.markers
                            if m.ns == "link_map/laptop"], default=0)
            self.assertTrue(wait_for(lambda: laptop_cells() >= 4, 60.0),
                            f"no link map of the laptop on ~link_map: {markers[-1:]}")
            self.assertTrue(wait_for(lambda: any(
                "Mbit/s for" in kv.value for s in ahead[-3:] for kv in s.values
                if kv.key == "laptop"), 30.0), f"no forecast of the laptop: {ahead[-1:]}")
            self.assertTrue(wait_for(lambda: len(saved_cells(map_file)) >= 3, 30.0),
                            f"{map_file}: {saved_cells(map_file)}")
            cells = saved_cells(map_file)
            for (i, j), stats in cells:
                self.assertTrue(0 <= i <= LENGTH_M and j == 0, (i, j))
                self.assertEqual(stats.lost_fraction, 0.0)
                self.assertTrue(math.isfinite(stats.low_mbps) and stats.low_mbps > 0)
        finally:
            os.killpg(decision.pid, signal.SIGINT)
            decision.wait(timeout=30)
            reader.join(5.0)
        out = "".join(lines)
        self.assertNotIn("Traceback", out)
        self.assertIn(f"link map {map_file}: version: expected 1, got 7; starting with an "
                      "empty one", out)
        self.assertIn("link forecast available", out)
        self.assertIn(f"link map saved to {map_file}", out)
        self.assertGreaterEqual(len(saved_cells(map_file)), len(cells))


if __name__ == "__main__":
    rostest.rosrun("anyscale_core", "decision_link_forecast", DecisionLinkForecastTest)
