#!/usr/bin/python3
"""rostest: a robot started with a wrong belief, every trajectory in collision, turns in place
(navigation's rotate recovery), relocalises and drives on."""
import math
import unittest

import rospy
import rostest
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Log


class LostStart(unittest.TestCase):
    def test_turns_relocalises_and_drives_on(self):
        rospy.init_node("lost_start_run")
        truth, amcl, turns = [], [], []
        rospy.Subscriber("/sim/ground_truth", Odometry, lambda m: truth.append(
            (m.pose.pose.position.x, m.pose.pose.position.y)))
        rospy.Subscriber("/amcl_pose", PoseWithCovarianceStamped, lambda m: amcl.append(
            (m.pose.pose.position.x, m.pose.pose.position.y)))
        rospy.Subscriber("/rosout_agg", Log, lambda m: turns.append(m.msg)
                         if m.name == "/navigation" and "turning in place" in m.msg else None)
        drive = rospy.get_param("~drive_m", 1.0)
        deadline = rospy.get_time() + rospy.get_param("~timeout", 60.0)

        def driven():
            return truth and math.dist(truth[0], truth[-1]) >= drive
        while not rospy.is_shutdown() and rospy.get_time() < deadline and not driven():
            rospy.sleep(0.2)
        self.assertTrue(turns, "navigation never turned in place")
        self.assertTrue(driven(), "the robot did not drive %.1f m within the timeout" % drive)
        error = math.dist(truth[-1], amcl[-1])
        rospy.loginfo("lost start: %s; AMCL %.2f m from the truth after %.1f m", turns[0],
                      error, math.dist(truth[0], truth[-1]))
        self.assertLess(error, rospy.get_param("~max_error", 0.3))


if __name__ == "__main__":
    rostest.rosrun("anyscale_nav_demo", "lost_start_run", LostStart)
