#!/usr/bin/python3
"""rostest: the agent's topic rates against rostopic hz (and hztest, run on the same topics in
the same launch), its CPU % against psutil, and that it subscribes only where a local node does."""
import os
import sys
import time
import unittest

import psutil
import rosgraph
import rospy
import rostest
import rostopic
from anyscale_msgs.msg import NodeProcess

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from agent_test_util import Agent, registered_pid, wait_for  # noqa: E402

RATES = {"/hz10": 10.0, "/hz40": 40.0, "/hz100": 100.0}
AGENT = "/anyscale_agent_robot"


def agent_subscribes(topic):
    _, subscribers, _ = rosgraph.Master("/agent_test").getSystemState()
    return any(t == topic and AGENT in nodes for t, nodes in subscribers)


def topic_stats(status, topic):
    for t in status.topics:
        if t.topic == topic:
            return t
    return None


class AgentAccuracyTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("agent_accuracy_test")
        cls.agent = Agent("robot")

    def test_rates_match_rostopic_hz(self):
        hz = rostopic.ROSTopicHz(-1)  # unbounded window: every message since subscription
        subs = [rospy.Subscriber(t, rospy.AnyMsg, hz.callback_hz, callback_args=t) for t in RATES]
        try:
            # The agent subscribes once it sees a local subscriber (ours), within its graph period.
            self.assertTrue(wait_for(lambda: all(agent_subscribes(t) for t in RATES), 10.0))
            time.sleep(3.0)  # fill the agent's 2 s window
            first = len(self.agent.statuses)
            with hz.lock:  # restart rostopic hz's measurement at the same moment
                for t in RATES:
                    hz.set_msg_t0(-1, topic=t)
            time.sleep(6.0)
            samples = self.agent.statuses[first:]
            self.assertGreaterEqual(len(samples), 8)  # 2 Hz status
            for topic, nominal in RATES.items():
                ref = hz.get_hz(topic)[0]  # (rate, min, max, std, n)
                mine = [topic_stats(s, topic).rate_hz for s in samples if topic_stats(s, topic)]
                mean = sum(mine) / len(mine)
                rospy.loginfo("%s: agent %.3f Hz, rostopic hz %.3f Hz, nominal %.1f",
                              topic, mean, ref, nominal)
                self.assertAlmostEqual(mean / ref, 1.0, delta=0.02, msg=topic)
                # hztest checks the publisher against the nominal rate in this launch.
                self.assertAlmostEqual(mean / nominal, 1.0, delta=0.05, msg=topic)
                last = topic_stats(samples[-1], topic)
                self.assertEqual(last.datatype, "std_msgs/String")
                self.assertLess(last.last_message_age_s, 3.0 / nominal)
                self.assertGreater(last.bytes_per_second, 0.0)
                self.assertLessEqual(last.interval_min_s, 1.0 / nominal + 1e-3)
        finally:
            for s in subs:
                s.unregister()

    def test_no_subscription_without_a_local_subscriber(self):
        time.sleep(2.0)
        self.assertFalse(agent_subscribes("/lonely"))
        self.assertIsNone(topic_stats(self.agent.statuses[-1], "/lonely"))
        sub = rospy.Subscriber("/lonely", rospy.AnyMsg, lambda m: None)
        try:
            self.assertTrue(wait_for(lambda: agent_subscribes("/lonely"), 10.0))
            self.assertTrue(wait_for(lambda: topic_stats(self.agent.statuses[-1], "/lonely"), 10.0))
        finally:
            sub.unregister()
        # Once nobody here listens, the agent lets go too.
        self.assertTrue(wait_for(lambda: not agent_subscribes("/lonely"), 10.0))

    def _cpu_against_psutil(self, node):
        res = self.agent.start(node=node, param_overrides=[], lease_s=0.0)
        self.assertTrue(res.success, res.message)
        try:
            self.assertTrue(wait_for(lambda: registered_pid("/" + node), 20.0))
            self.assertTrue(wait_for(
                lambda: self.agent.node("/" + node).state == NodeProcess.RUNNING, 10.0))
            leader = psutil.Process(res.pid)
            procs = [leader] + leader.children(recursive=True)
            time.sleep(2.0)
            first = len(self.agent.statuses)
            t0, c0 = time.monotonic(), sum(sum(p.cpu_times()[:2]) for p in procs)
            time.sleep(5.0)
            t1, c1 = time.monotonic(), sum(sum(p.cpu_times()[:2]) for p in procs)
            reference = 100.0 * (c1 - c0) / (t1 - t0)
            samples = [n.cpu_percent for s in self.agent.statuses[first + 1:]
                       for n in s.nodes if n.name == "/" + node]
            self.assertGreaterEqual(len(samples), 6)
            mean = sum(samples) / len(samples)
            rospy.loginfo("%s: agent %.1f %%, psutil %.1f %% of a core", node, mean, reference)
            self.assertGreater(reference, 25.0)  # the fixture really burns
            self.assertAlmostEqual(mean, reference, delta=10.0)
            rss = [n.rss_bytes for n in self.agent.statuses[-1].nodes if n.name == "/" + node][0]
            self.assertAlmostEqual(rss / sum(p.memory_info().rss for p in procs), 1.0, delta=0.2)
            return procs
        finally:
            self.agent.stop(node=node, wait=True)

    def test_cpu_percent_matches_psutil(self):
        self._cpu_against_psutil("burner")

    def test_cpu_of_a_wrapped_node_is_its_workers(self):
        # The leader is an idle shell; the CPU is spent by its child in the same process group.
        procs = self._cpu_against_psutil("wrapped_burner")
        self.assertEqual(len(procs), 2)
        self.assertTrue(wait_for(
            lambda: not any(p.is_running() and p.status() != psutil.STATUS_ZOMBIE for p in procs),
            10.0))

    def test_diagnostics(self):
        from diagnostic_msgs.msg import DiagnosticArray
        names = set()
        end = time.monotonic() + 10.0
        while time.monotonic() < end and not {"nodes", "scale", "link", "topics"} <= names:
            msg = rospy.wait_for_message("/diagnostics", DiagnosticArray, timeout=10.0)
            names |= {s.name.split(": ")[-1] for s in msg.status if s.hardware_id == "robot"}
        self.assertLessEqual({"nodes", "scale", "link", "topics"}, names)

    def test_scale_figures(self):
        s = self.agent.statuses[-1]
        self.assertEqual(s.cores, psutil.cpu_count())
        self.assertEqual(s.memory_total_bytes, psutil.virtual_memory().total)
        self.assertTrue(0.0 <= s.cpu_percent <= 100.0)
        self.assertAlmostEqual(s.sample_period_s, 0.5, delta=0.2)
        self.assertTrue(s.is_master)
        self.assertTrue(s.link.up)


if __name__ == "__main__":
    rostest.rosrun("anyscale_agent_cpp", "agent_accuracy", AgentAccuracyTest, sys.argv)
