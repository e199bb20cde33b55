#!/usr/bin/python3
"""Test fixture node (rospy): a correctness probe for `anyscale thresholds` tests. Publishes on
`rate` (std_msgs/Float64, 5 Hz) how many messages arrived on `input` (remap it; any type) in
the last `~window_s` seconds (default 1), so a condition such as `m.data >= 4` holds while the
input keeps its rate up and fails when it is throttled lower or cut for long enough."""
import collections
import time

import rospy
from std_msgs.msg import Float64


def main():
    rospy.init_node("rate_probe")
    window_s = float(rospy.get_param("~window_s", 1.0))
    arrivals = collections.deque()
    rospy.Subscriber("input", rospy.AnyMsg, lambda _m: arrivals.append(time.monotonic()),
                     queue_size=100)
    publisher = rospy.Publisher("rate", Float64, queue_size=10)
    rate = rospy.Rate(5)
    while not rospy.is_shutdown():
        now = time.monotonic()
        while arrivals and arrivals[0] < now - window_s:
            arrivals.popleft()
        publisher.publish(Float64(float(len(arrivals))))
        rate.sleep()


if __name__ == "__main__":
    main()
