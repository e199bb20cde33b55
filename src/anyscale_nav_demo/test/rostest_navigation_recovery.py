#!/usr/bin/python3
"""rostest: navigation, every trajectory colliding, stands for recovery_after_s, turns in place
(rotate recovery) until the turn times out, then gives up and stands still."""
import unittest

import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped, Twist

AFTER_S, TURN_TIMEOUT_S = 2.0, 2.0       # navigation_recovery.test
WATCH_S = 12.0
BELIEVED = (4.9, 4.3)   # 0.2 m from the small loop's inner block: inside the robot's radius


def phases(commands):
    """[(kind, first t, last t)] of consecutive commands: "stand" (all zero), "turn" (in place,
    counter-clockwise) or "drive"."""
    out = []
    for t, v, w in commands:
        kind = "stand" if v == 0 and w == 0 else "turn" if v == 0 and w > 0 else "drive"
        if out and out[-1][0] == kind:
            out[-1][2] = t
        else:
            out.append([kind, t, t])
    return out


class NavigationRecovery(unittest.TestCase):
    def test_stands_turns_then_gives_up(self):
        rospy.init_node("navigation_recovery")
        believed = TransformStamped()
        believed.header.stamp, believed.header.frame_id = rospy.Time.now(), "map"
        believed.child_frame_id = "base_link"
        believed.transform.translation.x, believed.transform.translation.y = BELIEVED
        believed.transform.rotation.w = 1.0
        broadcaster = tf2_ros.StaticTransformBroadcaster()
        broadcaster.sendTransform(believed)
        commands = []
        rospy.Subscriber("/cmd_vel", Twist, lambda m: commands.append(
            (rospy.get_time(), m.linear.x, m.angular.z)))
        # Corrections at 5 Hz: the safe-speed rule lets the robot move.
        pose = rospy.Publisher("/amcl_pose", PoseWithCovarianceStamped, queue_size=1)
        end = rospy.get_time() + WATCH_S
        while not rospy.is_shutdown() and rospy.get_time() < end:
            pose.publish(PoseWithCovarianceStamped())
            rospy.sleep(0.2)
        seen = phases(commands)
        rospy.loginfo("navigation's commands: %s", seen)
        kinds = [p[0] for p in seen]
        self.assertEqual(kinds, ["stand", "turn", "stand"], seen)
        stand, turn, gave_up = seen
        self.assertGreaterEqual(turn[1] - stand[1], AFTER_S - 0.2)
        self.assertAlmostEqual(turn[2] - turn[1], TURN_TIMEOUT_S, delta=0.4)
        self.assertGreater(gave_up[2] - gave_up[1], 3.0)


if __name__ == "__main__":
    rostest.rosrun("anyscale_nav_demo", "navigation_recovery", NavigationRecovery)
