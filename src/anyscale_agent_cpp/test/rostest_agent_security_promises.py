#!/usr/bin/python3
"""rostest: requests that are well-formed but do more than the agent's contract allows (issue
37): leases removed or shortened, pauses of nodes not declared pause_at_home, a tiny request
that claims millions of entries, the agent's own configuration changed on the parameter server,
overrides outside the state hand-off, watch lists naming subscribers the model does not have, a
shutdown over ROS that stopped the robot's drivers."""
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
import unittest

import genpy
import rosnode
import rospy
import rostest
from anyscale_msgs.msg import LinkProbe, NodeProcess
from anyscale_msgs.srv import RenewLeases, SetWatchedTopics, StartNode
from catkin.find_in_workspaces import find_in_workspaces
from diagnostic_msgs.msg import KeyValue

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from agent_test_util import (Agent, peak_rss, raw_service_call, registered_pid,  # noqa: E402
                             wait_for)

MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "config", "test_model.yaml")
# 60 million names in a 12-byte request: roscpp sized the vector before it saw the bytes.
CLAIMED = 60_000_000


class ForgedProbe(genpy.Message):
    """A LinkProbe on the wire whose payload claims 2e9 bytes and carries none."""
    _type, _md5sum, _full_text = LinkProbe._type, LinkProbe._md5sum, LinkProbe._full_text
    _has_header = False
    __slots__ = []

    def serialize(self, buff):
        buff.write(struct.pack("<I", 5) + b"robot" + struct.pack("<IBI", 1, 1, 2_000_000_000))


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open("/proc/%d/stat" % pid) as f:
        return f.read().rsplit(")", 1)[1].split()[0] != "Z"


def agent_binary():
    found = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                               first_matching_workspace_only=True)
    assert found, "anyscale_agent binary not built"
    return found[0]


class AgentPromisesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("agent_security_promises_test")
        cls.robot = Agent("robot")
        cls.laptop = Agent("laptop")
        cls.robot_pid = wait_for(lambda: registered_pid("/anyscale_agent_robot"), 10.0)

    @staticmethod
    def _running(agent, node):
        return wait_for(lambda: agent.node(node).state == NodeProcess.RUNNING, 20.0)

    def _start(self, agent, node, lease_s=0.0, overrides=()):
        kv = [KeyValue(key=k, value=v) for k, v in overrides]
        return agent.start(node=node, param_overrides=kv, lease_s=lease_s)

    def test_the_master_scale_takes_no_lease(self):
        # start_node{<a robot driver>, lease_s: 1e-6} got the driver SIGKILLed at the expiry.
        res = self._start(self.robot, "talker_cpp", lease_s=1e-6)
        self.assertFalse(res.success, res.message)
        self.assertIn("no lease on the master scale", res.message)
        res = self._start(self.robot, "talker_cpp")
        self.assertTrue(res.success, res.message)
        try:
            again = self._start(self.robot, "talker_cpp", lease_s=1e-6)
            self.assertFalse(again.success, again.message)
            self.assertTrue(self._running(self.robot, "/talker_cpp"))
            self.assertEqual(self.robot.node("/talker_cpp").lease_expiry.to_sec(), 0.0)
        finally:
            self.robot.stop(node="talker_cpp", wait=True)

    def test_a_running_nodes_lease_is_never_removed_or_shortened(self):
        res = self._start(self.laptop, "talker_cpp", lease_s=6.0)
        self.assertTrue(res.success, res.message)
        try:
            # Each answer dates the same end anew in ROS time: a few nanoseconds apart.
            expiry = self.laptop.node("/talker_cpp").lease_expiry.to_sec()
            self.assertGreater(expiry, 0.0)
            # lease_s 0 removed the lease: a partition then left two instances running.
            again = self._start(self.laptop, "talker_cpp", lease_s=0.0)
            self.assertEqual((again.success, again.pid), (True, res.pid), again.message)
            self.assertGreater(self.laptop.node("/talker_cpp").lease_expiry.to_sec(), expiry - 0.01)
            # A lease of a microsecond, by a start or a renewal, ended it at once.
            self.assertTrue(self._start(self.laptop, "talker_cpp", lease_s=1e-6).success)
            self.assertTrue(self.laptop.renew(nodes=["talker_cpp"], lease_s=1e-6).success)
            time.sleep(1.0)
            node = self.laptop.node("/talker_cpp")
            self.assertEqual(node.state, NodeProcess.RUNNING)
            self.assertGreater(node.lease_expiry.to_sec(), expiry - 0.01)
            # Renewed it is: the end moves later.
            self.assertTrue(self.laptop.renew(nodes=["talker_cpp"], lease_s=20.0).success)
            self.assertGreater(self.laptop.node("/talker_cpp").lease_expiry.to_sec(), expiry + 5.0)
        finally:
            self.laptop.stop(node="talker_cpp", wait=True)

    def test_a_pause_needs_pause_at_home_in_the_model(self):
        res = self._start(self.robot, "talker_cpp")
        self.assertTrue(res.success, res.message)
        try:
            self.assertTrue(self._running(self.robot, "/talker_cpp"))
            paused = self.robot.stop(node="talker_cpp", pause=True)
            self.assertFalse(paused.success, paused.message)
            self.assertIn("pause_at_home", paused.message)
            self.assertEqual(self.robot.node("/talker_cpp").state, NodeProcess.RUNNING)
            with open("/proc/%d/stat" % res.pid) as f:
                self.assertNotEqual(f.read().rsplit(")", 1)[1].split()[0], "T")
        finally:
            self.robot.stop(node="talker_cpp", wait=True)

    def test_a_tiny_request_claiming_millions_of_entries_fails_and_costs_nothing(self):
        victim = self._start(self.robot, "talker_cpp")
        self.assertTrue(victim.success, victim.message)
        try:
            before = peak_rss(self.robot_pid)
            claims = [
                ("renew_leases", RenewLeases, struct.pack("<I", CLAIMED) + struct.pack("<f", 1.0)),
                ("start_node", StartNode,
                 struct.pack("<I", 4) + b"amcl" + struct.pack("<Ifff", CLAIMED, 0.0, 0.0, 0.0)),
                ("set_watched_topics", SetWatchedTopics, struct.pack("<II", CLAIMED, 0)),
            ]
            answers = [(service, raw_service_call("/anyscale/robot/" + service, srv._md5sum, body))
                       for service, srv, body in claims]
            # A link probe whose payload claims 2 GB, on the topic the master's agent echoes.
            probe = rospy.Publisher("/anyscale/link/probe", ForgedProbe, queue_size=1)
            self.assertTrue(wait_for(lambda: probe.get_num_connections() > 0, 10.0))
            probe.publish(ForgedProbe())
            time.sleep(1.0)
            probe.unregister()
            grew = peak_rss(self.robot_pid) - before
            print("peak RSS of the robot's agent after the claims: %+.1f MB" % (grew / 1e6))
            self.assertLess(grew, 64 << 20, "peak RSS grew %.0f MB" % (grew / 1e6))
            for service, (ok, answer) in answers:
                self.assertEqual(ok, 0, (service, answer))
                self.assertIn(b"claims", answer, service)
            # It answers the next well-formed request, and nothing else died.
            renewed = self.robot.renew(nodes=["ghost"], lease_s=1.0)
            self.assertEqual(renewed.not_running, ["ghost"])
            self.assertEqual(registered_pid("/anyscale_agent_robot"), self.robot_pid)
            self.assertIsNotNone(registered_pid("/anyscale_agent_laptop"))
            self.assertTrue(alive(victim.pid))
        finally:
            self.robot.stop(node="talker_cpp", wait=True)

    def test_overrides_are_only_the_models_state_hand_off(self):
        for key, value in (("rate", "2147483647"), ("update_min_d", ".nan"), ("text", "1")):
            res = self._start(self.robot, "talker_py", overrides=[(key, value)])
            self.assertEqual((res.success, res.pid), (False, 0), (key, res.message))
            self.assertIn("state hand-off", res.message)
        res = self._start(self.robot, "talker_cpp", overrides=[("initial_pose_x", "1.5")])
        self.assertFalse(res.success, res.message)          # declares no hand-off
        res = self._start(self.robot, "talker_py", overrides=[("initial_pose_x", "1.5")])
        self.assertTrue(res.success, res.message)
        try:
            self.assertEqual(rospy.get_param("/talker_py/initial_pose_x"), 1.5)
        finally:
            self.robot.stop(node="talker_py", wait=True)

    def test_watch_list_subscribers_are_the_models(self):
        # An undeclared pair made the laptop's agent pull a camera stream across the link.
        for topics, subscribers in ((["/py_chatter"], ["/relay_cpp_chatter"]),
                                    (["/cpp_chatter"], ["/camera_driver"])):
            res = self.laptop.set_watched(topics=topics, subscribers=subscribers)
            self.assertFalse(res.success, (topics, subscribers))
            self.assertIn("model", res.message)
        res = self.laptop.set_watched(topics=["/cpp_chatter", "/other"],
                                      subscribers=["/relay_cpp_chatter", ""])
        self.assertTrue(res.success, res.message)
        self.laptop.set_watched(topics=[])

    def test_the_agents_own_configuration_is_not_read_from_the_parameter_server(self):
        # rosparam set ~state_file /etc/<file>, then a restart: the agent replaced that file.
        # Each restart leaves out of its command line what it tests, as roscpp would otherwise
        # put the command line's value back on the parameter server.
        work = tempfile.mkdtemp(prefix="anyscale_promises_")
        self.addCleanup(shutil.rmtree, work, True)
        victim, elsewhere = os.path.join(work, "victim"), os.path.join(work, "elsewhere")
        with open(victim, "w") as f:
            f.write("precious\n")
        evil = os.path.join(work, "evil.yaml")
        with open(evil, "w") as f:
            f.write("nodes: [{name: evil, launch: {package: anyscale_agent_cpp, "
                    "type: talker.py}}]\n")
        base = [agent_binary(), "__name:=anyscale_agent_cfg", "_scale:=cfg", "_warm_start:=false"]
        model, log_dir = "_model:=" + MODEL, "_log_dir:=" + os.path.join(work, "log")
        self._serve_and_stop(base + [model, log_dir])
        for key, value in (("state_file", victim), ("model", evil), ("log_dir", elsewhere),
                           ("is_master", True), ("scale", "robot"), ("ledger_file", victim),
                           ("robot", "intruder")):
            rospy.set_param("/anyscale_agent_cfg/" + key, value)
        # Without _model:= it does not take the one on the parameter server: it does not start.
        proc = subprocess.Popen(base + [log_dir], stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        try:
            _, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        self.assertNotEqual(proc.returncode, 0)
        self.assertIn(b"_model:=", err)
        # Without _log_dir:= neither: its default, not the one on the parameter server.
        self._serve_and_stop(base + [model])
        with open(victim) as f:
            self.assertEqual(f.read(), "precious\n")
        self.assertFalse(os.path.exists(elsewhere))

    def test_a_shutdown_over_ros_leaves_the_nodes_running_for_the_next_agent(self):
        # rosnode kill (XML-RPC shutdown, anyone's to call) of the robot's agent stopped every
        # node, the drivers too, and nothing started them again.
        work = tempfile.mkdtemp(prefix="anyscale_promises_")
        self.addCleanup(shutil.rmtree, work, True)
        command = [agent_binary(), "__name:=anyscale_agent_keep", "_scale:=keep",
                   "_model:=" + MODEL, "_warm_start:=false", "_nodes_outlive_agent:=true",
                   "_log_dir:=" + os.path.join(work, "log")]
        proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        pid = 0
        try:
            res = self._start(Agent("keep"), "talker_cpp")
            self.assertTrue(res.success, res.message)
            pid = res.pid
            self.assertEqual(rosnode.kill_nodes(["/anyscale_agent_keep"])[1], [])
            self.assertEqual(proc.wait(timeout=30), 0)
            self.assertTrue(alive(pid), "the shutdown over ROS stopped the node")
            # The next agent adopts it; a signal to that one stops it.
            proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            successor = Agent("keep")
            self.assertTrue(self._running(successor, "/talker_cpp"))
            self.assertEqual(successor.node("/talker_cpp").pid, pid)
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=30)
            self.assertTrue(wait_for(lambda: not alive(pid), 10.0))
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            if pid and alive(pid):
                os.kill(pid, signal.SIGKILL)

    def _serve_and_stop(self, command):
        """Runs the agent `command`, checks it serves its model's nodes and not 'evil', and
        ends it with SIGTERM."""
        proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            agent = Agent("cfg")
            res = self._start(agent, "talker_cpp")
            self.assertTrue(res.success, res.message)
            self.assertFalse(self._start(agent, "evil").success)
            self.assertTrue(agent.stop(node="talker_cpp", wait=True).success)
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=30)


if __name__ == "__main__":
    rostest.rosrun("anyscale_agent_cpp", "agent_security_promises", AgentPromisesTest, sys.argv)
