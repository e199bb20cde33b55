#!/usr/bin/python3
"""rostest: the small loop completes, markers are recognised, localisation tracks ground truth."""
import unittest

import numpy as np
import rospy
import rostest
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from anyscale_nav_demo.results import localisation_errors


class SmallLoop(unittest.TestCase):
    def test_loop(self):
        rospy.init_node("small_loop_run")
        truth, amcl, ekf, seen, status = [], [], [], set(), [""]
        rospy.Subscriber("/sim/ground_truth", Odometry, lambda m: truth.append(
            (m.header.stamp.to_sec(), m.pose.pose.position.x, m.pose.pose.position.y)))
        rospy.Subscriber("/amcl_pose", PoseWithCovarianceStamped, lambda m: amcl.append(
            (m.header.stamp.to_sec(), m.pose.pose.position.x, m.pose.pose.position.y)))
        rospy.Subscriber("/odometry/filtered", Odometry, lambda m: ekf.append(
            (m.header.stamp.to_sec(), m.pose.pose.position.x, m.pose.pose.position.y)))
        rospy.Subscriber("/ar_markers", MarkerArray, lambda m: seen.update(k.id for k in m.markers))
        rospy.Subscriber("/navigation/status", String, lambda m: status.__setitem__(0, m.data))
        deadline = rospy.get_time() + rospy.get_param("~timeout", 180.0)
        while (not rospy.is_shutdown() and rospy.get_time() < deadline
               and not status[0].startswith("done")):
            rospy.sleep(0.5)
        self.assertEqual(status[0], "done 5/5", "navigation did not complete the loop in time")
        self.assertEqual(sorted(seen), [0, 1, 2, 3])
        t = np.array(truth)
        travelled = np.sum(np.hypot(*np.diff(t[:, 1:], axis=0).T))
        self.assertGreater(travelled, 15.0)
        limit = rospy.get_param("~max_rms_error", 0.3)
        for name, est in (("amcl", amcl), ("ekf", ekf)):
            e = np.array(est)
            err = localisation_errors(t[:, 0], t[:, 1:], e[:, 0], e[:, 1:])
            rms = float(np.sqrt(np.mean(err ** 2)))
            rospy.loginfo("%s: RMS error %.3f m over %d poses, max %.3f m",
                          name, rms, len(err), err.max())
            self.assertGreater(len(err), 50)
            self.assertLess(rms, limit, "%s RMS error %.3f m" % (name, rms))


if __name__ == "__main__":
    rostest.rosrun("anyscale_nav_demo", "small_loop_run", SmallLoop)
