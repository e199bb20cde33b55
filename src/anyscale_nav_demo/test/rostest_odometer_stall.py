#!/usr/bin/python3
"""rostest: wheels turning steadily, the odometer driver stopped (SIGSTOP) for half a second
while encoder frames queue up; the joint velocities it reports after that stay the true ones
(stamped on arrival, the backlog's frames came microseconds apart: 300-6000 rad/s)."""
import math
import os
import signal
import unittest
import xmlrpc.client

import rosgraph
import rospy
import rostest
from sensor_msgs.msg import JointState
from std_msgs.msg import Int64MultiArray

TICKS_PER_REV = 4096
WHEEL_RAD_S = 4.0          # 0.2 m/s on 5 cm wheels
RATE_HZ = 40.0


def node_pid(name):
    uri = rosgraph.Master(rospy.get_name()).lookupNode(name)
    code, _, pid = xmlrpc.client.ServerProxy(uri).getPid(rospy.get_name())
    if code != 1:
        raise RuntimeError("no pid for %s" % name)
    return pid


class OdometerStall(unittest.TestCase):
    def test_backlog_gives_no_velocity_spike(self):
        rospy.init_node("odometer_stall")
        velocities = []
        rospy.Subscriber("joint_states", JointState,
                         lambda m: velocities.append(max(map(abs, m.velocity))))
        pub = rospy.Publisher("/sim/encoders/ticks", Int64MultiArray, queue_size=100)
        start = rospy.get_time()
        ticks_per_s = WHEEL_RAD_S / (2 * math.pi) * TICKS_PER_REV

        latched = [0]               # frames the encoder board has latched so far

        def publish_for(seconds):
            # The board latches at 40 Hz whatever delivery does. Latching at this process's
            # `now` put frames microseconds apart whenever a busy machine delayed the test
            # and rospy.Rate caught up, and one tick over them read as 10+ rad/s.
            end = rospy.get_time() + seconds
            rate = rospy.Rate(RATE_HZ)
            while rospy.get_time() < end:
                latch = start + latched[0] / RATE_HZ
                latched[0] += 1
                n = int((latch - start) * ticks_per_s)
                pub.publish(Int64MultiArray(data=[n, n, int(latch * 1e9)]))
                rate.sleep()

        deadline = rospy.get_time() + 20.0
        while not velocities and rospy.get_time() < deadline:
            publish_for(0.5)
        self.assertTrue(velocities, "the driver published no joint_states")
        pid = node_pid("/odometer")
        for _ in range(3):
            os.kill(pid, signal.SIGSTOP)
            try:
                publish_for(0.5)        # 20 frames queue up while the driver is stopped
            finally:
                os.kill(pid, signal.SIGCONT)
            publish_for(1.0)
        settled = velocities[2:]        # the first reading has no velocity yet
        self.assertGreater(len(settled), 60)
        # Tick quantisation and the publisher's own jitter allow some error; a backlog stamped
        # on arrival gives ten times the true speed and more.
        self.assertLess(max(settled), 2.0 * WHEEL_RAD_S, sorted(settled)[-5:])


if __name__ == "__main__":
    rostest.rosrun("anyscale_nav_demo", "odometer_stall", OdometerStall)
