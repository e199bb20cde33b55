#!/usr/bin/python3
"""rostest: with AMCL killed mid-drive, navigation's speed limit falls and the robot stops."""
import math
import unittest

import rosnode
import rospy
import rostest
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64


class AmclLoss(unittest.TestCase):
    def test_stops_without_localisation(self):
        rospy.init_node("amcl_loss")
        speed, limit = [0.0, 0.0], [None]
        rospy.Subscriber("/sim/ground_truth", Odometry, lambda m: speed.__setitem__(
            0, math.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y)))
        rospy.Subscriber("/sim/ground_truth", Odometry, lambda m: speed.__setitem__(
            1, abs(m.twist.twist.angular.z)))
        rospy.Subscriber("/navigation/speed_limit", Float64, lambda m: limit.__setitem__(0, m.data))
        deadline = rospy.get_time() + 60.0
        while speed[0] < 0.3 and rospy.get_time() < deadline:
            rospy.sleep(0.1)
        self.assertGreaterEqual(speed[0], 0.3, "the robot never got going")
        self.assertAlmostEqual(limit[0], 0.4, delta=0.05)
        rosnode.kill_nodes(["/amcl"])
        killed = rospy.get_time()
        limits = []
        while rospy.get_time() - killed < 6.0:
            limits.append((rospy.get_time() - killed, limit[0], speed[0], speed[1]))
            rospy.sleep(0.1)
        # Slows first (speed limit = d_max / age of the last correction), then stops at the
        # 2 s tolerance; the base decelerates within a second after that.
        self.assertTrue(any(0.0 < lim < 0.3 for _, lim, _, _ in limits), limits)
        after = [(lin, ang) for t, _, lin, ang in limits if t > 4.0]
        self.assertTrue(all(lim == 0.0 for t, lim, _, _ in limits if t > 2.5), limits)
        self.assertTrue(all(lin < 0.02 and ang < 0.05 for lin, ang in after), after)


if __name__ == "__main__":
    rostest.rosrun("anyscale_nav_demo", "amcl_loss", AmclLoss)
