#!/usr/bin/python3
"""rostest: two agents on one box: link statistics up and down, and one node's instances on
both scales side by side under their per-scale names."""
import math
import os
import subprocess
import sys
import time
import unittest

import rospy
import rostest
from anyscale_msgs.msg import NodeProcess
from diagnostic_msgs.msg import KeyValue

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from agent_test_util import Agent, registered_pid, wait_for  # noqa: E402

MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "config", "test_model.yaml")


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open("/proc/%d/stat" % pid) as f:
        return f.read().rsplit(")", 1)[1].split()[0] != "Z"


def agent_binary():
    from catkin.find_in_workspaces import find_in_workspaces
    return find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                              first_matching_workspace_only=True)[0]


class TwoScalesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("agent_two_scales_test")
        cls.laptop = Agent("laptop")

    def _start_master(self):
        proc = subprocess.Popen([agent_binary(), "__name:=anyscale_agent_robot", "_scale:=robot",
                                 "_is_master:=true", "_model:=" + MODEL, "_sigint_timeout_s:=3.0"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.addCleanup(lambda: proc.poll() is not None or (proc.terminate(), proc.wait()))
        return proc

    def _link(self):
        return self.laptop.statuses[-1].link if self.laptop.statuses else None

    def test_link_up_down_up(self):
        master = self._start_master()
        self.assertTrue(wait_for(lambda: self._link() and self._link().up, 15.0),
                        "link never came up")
        # A bulk probe every second: the estimate appears within a few seconds.
        self.assertTrue(wait_for(lambda: not math.isnan(self._link().bandwidth_mbps), 10.0))
        link = self._link()
        self.assertEqual(link.peer_scale, "robot")
        self.assertLess(link.rtt_mean_s, 0.1)
        self.assertGreater(link.rtt_s, 0.0)
        self.assertGreater(link.bandwidth_mbps, 1.0)  # loopback: far above any WiFi
        master.terminate()
        master.wait(timeout=20)
        self.assertTrue(wait_for(lambda: not self._link().up, 5.0),
                        "link still up with the master agent gone")
        self.assertTrue(wait_for(lambda: self._link().loss_ratio > 0.0, 5.0))
        self._start_master()
        self.assertTrue(wait_for(lambda: self._link().up, 15.0), "link did not come back")

    def test_lease_renewed_keeps_running_then_expires(self):
        # Away from the master scale: there a node runs under a lease.
        res = self.laptop.start(node="talker_cpp", param_overrides=[], lease_s=2.0)
        self.assertTrue(res.success, res.message)
        try:
            self.assertGreater(self.laptop.node("/talker_cpp").lease_expiry.to_sec(), 0.0)
            for _ in range(4):  # 4 s of renewals past a 2 s lease
                time.sleep(1.0)
                r = self.laptop.renew(nodes=["talker_cpp"], lease_s=2.0)
                self.assertTrue(r.success, r.message)
            self.assertTrue(alive(res.pid))
            bad = self.laptop.renew(nodes=["talker_cpp", "ghost"], lease_s=2.0)
            self.assertFalse(bad.success)
            self.assertEqual(bad.not_running, ["ghost"])
            # No more renewals: stopped by the agent itself.
            self.assertTrue(wait_for(
                lambda: self.laptop.node("/talker_cpp").state == NodeProcess.LEASE_EXPIRED, 10.0))
            self.assertTrue(wait_for(lambda: not alive(res.pid), 5.0))
            self.assertTrue(wait_for(lambda: registered_pid("/talker_cpp__laptop") is None, 5.0))
        finally:
            self.laptop.stop(node="talker_cpp", wait=True)

    def test_instances_on_two_scales_run_side_by_side_under_their_own_names(self):
        # The master's same-name rule would end the robot's instance when the laptop's
        # registered (and across a partition, the live one): a remote instance runs as
        # NAME__SCALE, with the declared node's private parameters copied under that name.
        self._start_master()
        robot = Agent("robot")
        first = robot.start(node="talker_py", param_overrides=[], lease_s=0.0)
        self.assertTrue(first.success, first.message)
        rospy.set_param("/talker_py/set_by_a_launch_file", 3)
        self.assertEqual(wait_for(lambda: registered_pid("/talker_py"), 20.0), first.pid)
        self.assertTrue(
            wait_for(lambda: robot.node("/talker_py").state == NodeProcess.RUNNING, 10.0))
        pose = KeyValue(key="initial_pose_x", value="12.5")
        second = self.laptop.start(node="talker_py", param_overrides=[pose], lease_s=10.0)
        self.assertTrue(second.success, second.message)
        try:
            self.assertEqual(wait_for(lambda: registered_pid("/talker_py__laptop"), 20.0),
                             second.pid)
            self.assertEqual(self.laptop.node("/talker_py").instance, "/talker_py__laptop")
            self.assertEqual(rospy.get_param("/talker_py__laptop/set_by_a_launch_file"), 3)
            self.assertEqual(rospy.get_param("/talker_py__laptop/initial_pose_x"), 12.5)
            self.assertFalse(rospy.has_param("/talker_py/initial_pose_x"))     # the robot's own
            # Both publish; the robot's instance is neither replaced nor shut down.
            callers = set()
            sub = rospy.Subscriber("/py_chatter", rospy.AnyMsg,
                                   lambda m: callers.add(m._connection_header["callerid"]))
            self.assertTrue(
                wait_for(lambda: callers >= {"/talker_py", "/talker_py__laptop"}, 10.0), callers)
            sub.unregister()
            self.assertEqual(registered_pid("/talker_py"), first.pid)
            self.assertEqual(robot.node("/talker_py").state, NodeProcess.RUNNING)
            # A start of a node already running is answered with its pid, nothing started.
            again = self.laptop.start(node="talker_py", param_overrides=[], lease_s=10.0)
            self.assertEqual((again.success, again.pid), (True, second.pid), again.message)
        finally:
            self.laptop.stop(node="talker_py", wait=True)
            robot.stop(node="talker_py", wait=True)
            rospy.delete_param("/talker_py")


if __name__ == "__main__":
    rostest.rosrun("anyscale_agent_cpp", "agent_two_scales", TwoScalesTest, sys.argv)
