#!/usr/bin/python3
"""Test fixture node (rospy) for test_link_shaper_root.py: gives the link_shaper a map with a
wall and a ground-truth pose, drives the pose somewhere and back, and prints one JSON line of
what the shaper answered (bandwidths, coverage grid, access-point marker)."""
import json
import sys
import time

import rospy
from nav_msgs.msg import OccupancyGrid, Odometry
from std_msgs.msg import Float32
from visualization_msgs.msg import Marker


def wall_map() -> OccupancyGrid:
    grid = OccupancyGrid()
    grid.header.frame_id = "map"
    grid.info.resolution, grid.info.width, grid.info.height = 0.1, 100, 100
    grid.info.origin.orientation.w = 1.0
    grid.data = ([0] * 50 + [100] * 2 + [0] * 48) * 100   # a wall at x = 5.0..5.2
    return grid


def main():
    rospy.init_node("link_shaper_probe", anonymous=True)
    map_pub = rospy.Publisher("/map", OccupancyGrid, queue_size=1, latch=True)
    pose_pub = rospy.Publisher("/sim/ground_truth", Odometry, queue_size=1)
    bandwidths = []
    rospy.Subscriber("/anyscale/wifi/bandwidth_mbps", Float32, lambda m: bandwidths.append(m.data))
    map_pub.publish(wall_map())

    def drive_to(x, y, expected):
        """Publishes the pose until the shaper reports `expected` (20 s at most); its last."""
        odom = Odometry()
        odom.header.frame_id = "map"
        odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
        odom.pose.pose.orientation.w = 1.0
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and (not bandwidths or bandwidths[-1] != expected):
            pose_pub.publish(odom)
            time.sleep(0.1)
        return bandwidths[-1] if bandwidths else None

    result = {"near": drive_to(float(sys.argv[1]), 5.0, 27.0),
              "far": drive_to(300.0, 5.0, 0.0)}                  # far off the floor
    coverage = rospy.wait_for_message("/anyscale/wifi/coverage", OccupancyGrid, timeout=20)
    result["coverage"] = {"size": [coverage.info.width, coverage.info.height],
                          "resolution": coverage.info.resolution,
                          "frame_id": coverage.header.frame_id,
                          "min": min(coverage.data), "max": max(coverage.data)}
    marker = rospy.wait_for_message("/anyscale/wifi/access_point", Marker, timeout=20)
    result["access_point"] = [marker.pose.position.x, marker.pose.position.y]
    print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
