#!/usr/bin/python3
"""rostest: AMCL waits for the odometry of a scan that came before it (~odom_wait_s), as
amcl's tf message filter does, instead of dropping the scan."""
import threading
import unittest

import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped
from nav_msgs.msg import OccupancyGrid
from sensor_msgs.msg import LaserScan
from tf2_msgs.msg import TFMessage

ODOM_LATE_S = 0.25          # after the scan; amcl's old fixed wait was 0.1 s


def square_room(cells=80, resolution=0.05):
    grid = OccupancyGrid()
    grid.header.frame_id = "map"
    grid.info.resolution, grid.info.width, grid.info.height = resolution, cells, cells
    grid.info.origin.orientation.w = 1.0
    grid.data = [100 if x in (0, cells - 1) or y in (0, cells - 1) else 0
                 for y in range(cells) for x in range(cells)]
    return grid


def transform(parent, child, stamp, x=0.0, y=0.0):
    t = TransformStamped()
    t.header.frame_id, t.header.stamp, t.child_frame_id = parent, stamp, child
    t.transform.translation.x, t.transform.translation.y = x, y
    t.transform.rotation.w = 1.0
    return t


class AmclLateOdometry(unittest.TestCase):
    def test_scan_waits_for_its_odometry(self):
        rospy.init_node("amcl_late_odom")
        poses = []
        rospy.Subscriber("/amcl_pose", PoseWithCovarianceStamped, poses.append)
        map_pub = rospy.Publisher("/map", OccupancyGrid, queue_size=1, latch=True)
        scan_pub = rospy.Publisher("/scan", LaserScan, queue_size=10)
        tf_pub = rospy.Publisher("/tf", TFMessage, queue_size=10)
        static = tf2_ros.StaticTransformBroadcaster()
        static.sendTransform(transform("base_link", "laser", rospy.Time(0)))
        map_pub.publish(square_room())
        rospy.sleep(1.0)
        scans = 0
        deadline = rospy.get_time() + 20.0
        while len(poses) < 3 and rospy.get_time() < deadline:
            stamp = rospy.Time.now()
            scan = LaserScan(angle_min=-1.5, angle_max=1.5, angle_increment=0.1, range_min=0.1,
                             range_max=5.0, ranges=[1.9] * 31)
            scan.header.stamp, scan.header.frame_id = stamp, "laser"
            scan_pub.publish(scan)
            scans += 1
            threading.Timer(ODOM_LATE_S, lambda s=stamp: tf_pub.publish(TFMessage(
                [transform("odom", "base_link", s, 2.0, 2.0)]))).start()
            rospy.sleep(0.4)
        self.assertGreaterEqual(len(poses), 3, "%d poses for %d scans whose odometry came %.2f s "
                                "after them" % (len(poses), scans, ODOM_LATE_S))
        # The estimate is saved for the next instance (a move's hand-over reads it), off the
        # scan's path: it appears on the parameter server by itself.
        deadline = rospy.get_time() + 5.0
        while rospy.get_param("/amcl/initial_pose_stamp", 0.0) <= 0.0 and \
                rospy.get_time() < deadline:
            rospy.sleep(0.1)
        saved = rospy.get_param("/amcl/initial_pose_stamp", 0.0)
        self.assertIn(saved, [p.header.stamp.to_sec() for p in poses],
                      "~initial_pose_stamp %.3f is not the stamp of a published pose" % saved)


if __name__ == "__main__":
    rostest.rosrun("anyscale_nav_demo", "amcl_late_odom", AmclLateOdometry)
