#!/usr/bin/python3
"""rostest: a watched topic that a node the agent runs subscribes to is counted from that node's
getBusStats (roscpp and rospy), close to the published rate, with no subscription of the agent's;
a frozen node leaves its topic without data and the agent's status running; the start boost of
a node still ends at its first output counted that way, and a node whose output is late is
boosted until its next message."""
import os
import signal
import statistics
import sys
import time
import unittest
import xmlrpc.client

import rosgraph
import rospy
import rostest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from agent_test_util import Agent, needs_root, wait_for  # noqa: E402

AGENT = "/anyscale_agent_robot"


def topic_stats(status, topic):
    return next((t for t in status.topics if t.topic == topic), None)


def subscribers_of(topic):
    """The master's subscribers of `topic`."""
    _, subscribers, _ = rosgraph.Master("/agent_test").getSystemState()
    return set(next((nodes for t, nodes in subscribers if t == topic), []))


def connected_subscribers(publisher, topic):
    """Who the publisher itself sends `topic` to (its getBusInfo): what crosses the wire."""
    uri = rosgraph.Master("/agent_test").lookupNode(publisher)
    _, _, info = xmlrpc.client.ServerProxy(uri).getBusInfo("/agent_test")
    return {c[1] for c in info if c[4] == topic and c[2] == "o"}


class AgentBusStatsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("agent_bus_stats_test")
        cls.agent = Agent("robot")

    def latest(self, topic):
        return topic_stats(self.agent.statuses[-1], topic) if self.agent.statuses else None

    def rate(self, topic):
        """The topic's rate in the latest status; 0 while the status does not show it."""
        return getattr(self.latest(topic), "rate_hz", 0.0) or 0.0

    def counted_from_bus(self, node, topic="/bus20", published_hz=20.0):
        res = self.agent.set_watched(topics=[topic], subscribers=["/" + node])
        self.assertTrue(res.success, res.message)
        started = self.agent.start(node=node, param_overrides=[], lease_s=0.0)
        self.assertTrue(started.success, started.message)
        try:
            self.assertTrue(wait_for(lambda: self.rate(topic) > 10.0, 20.0),
                            "no rate for %s while %s runs here" % (topic, node))
            # The window fills for 2 s; then 6 s of status samples, and the subscribers meanwhile.
            time.sleep(2.5)
            first = len(self.agent.statuses)
            rates, ages, bytes_s = [], [], []
            deadline = time.monotonic() + 6.0
            while time.monotonic() < deadline:
                self.assertEqual(subscribers_of(topic), {"/" + node})
                self.assertEqual(connected_subscribers("/pub_bus20", topic), {"/" + node})
                time.sleep(0.5)
            for status in self.agent.statuses[first:]:
                t = topic_stats(status, topic)
                self.assertIsNotNone(t)
                rates.append(t.rate_hz)
                ages.append(t.last_message_age_s)
                bytes_s.append(t.bytes_per_second)
            median = statistics.median(rates)
            print("%s counted from %s's bus statistics: rate median %.3f Hz [%.3f, %.3f] over %d "
                  "status samples (published %.1f Hz); last_message_age_s max %.3f; bytes/s "
                  "median %.1f" % (topic, node, median, min(rates), max(rates), len(rates),
                                   published_hz, max(ages), statistics.median(bytes_s)))
            self.assertGreaterEqual(len(rates), 8)
            self.assertLess(abs(median - published_hz), 0.05 * published_hz)
            for r in rates:
                self.assertLess(abs(r - published_hz), 0.15 * published_hz, rates)
            self.assertLess(max(ages), 0.5, ages)
            self.assertGreater(min(bytes_s), 0.0)
            return started.pid
        except BaseException:
            self.agent.stop(node=node, wait=True)
            raise

    def test_roscpp_subscriber_and_a_frozen_one(self):
        pid = self.counted_from_bus("relay_bus20")
        try:
            # Frozen: no reply to getBusStats. The status goes on at its rate, the topic's age
            # grows.
            os.kill(pid, signal.SIGSTOP)
            try:
                first = len(self.agent.statuses)
                time.sleep(3.0)
                self.assertGreaterEqual(len(self.agent.statuses) - first, 5, "the status stalled")
                t = self.latest("/bus20")
                print("relay_bus20 frozen 3 s: rate %.3f Hz, last_message_age_s %.3f"
                      % (t.rate_hz, t.last_message_age_s))
                self.assertGreater(t.last_message_age_s, 1.5)
                self.assertLess(t.rate_hz, 10.0)
                self.assertEqual(subscribers_of("/bus20"), {"/relay_bus20"})
            finally:
                os.kill(pid, signal.SIGCONT)
            self.assertTrue(wait_for(lambda: self.latest("/bus20").rate_hz > 18.0, 10.0),
                            "the rate did not come back after SIGCONT")
        finally:
            self.agent.stop(node="relay_bus20", wait=True)
        # Once the node is gone, nothing counts the topic here.
        self.assertTrue(wait_for(lambda: self.latest("/bus20") is None, 10.0))
        self.assertNotIn(AGENT, subscribers_of("/bus20"))

    def test_rospy_subscriber(self):
        self.counted_from_bus("listener_bus20")
        self.agent.stop(node="listener_bus20", wait=True)
        self.assertTrue(wait_for(lambda: self.latest("/bus20") is None, 10.0))

    def test_start_boost_ends_at_the_output_counted_from_bus_stats(self):
        needs_root(self, "the start boost raises a node's priority (nice -5): needs root or "
                   "CAP_SYS_NICE")
        res = self.agent.set_watched(topics=["/cpp_chatter"], subscribers=["/relay_cpp_chatter"])
        self.assertTrue(res.success, res.message)
        relay = self.agent.start(node="relay_cpp_chatter", param_overrides=[], lease_s=0.0)
        self.assertTrue(relay.success, relay.message)
        try:
            self.assertTrue(wait_for(lambda: self.latest("/cpp_chatter") is not None, 10.0))
            began = time.monotonic()
            talker = self.agent.start(node="talker_cpp", param_overrides=[], lease_s=0.0)
            self.assertTrue(talker.success, talker.message)
            try:
                self.assertTrue(
                    wait_for(lambda: os.getpriority(os.PRIO_PROCESS, talker.pid) == 0, 10.0),
                    "the talker's start boost did not end at its first output (nice %d)"
                    % os.getpriority(os.PRIO_PROCESS, talker.pid))
                print("talker_cpp's start boost ended %.2f s after its start"
                      % (time.monotonic() - began))
                self.assertTrue(wait_for(lambda: self.rate("/cpp_chatter") > 15.0, 10.0))
                self.assertEqual(subscribers_of("/cpp_chatter"), {"/relay_cpp_chatter"})
            finally:
                self.agent.stop(node="talker_cpp", wait=True)
        finally:
            self.agent.stop(node="relay_cpp_chatter", wait=True)

    def test_a_late_output_is_boosted_until_its_next_message(self):
        needs_root(self, "the late boost raises a node's priority (nice -5): needs root or "
                   "CAP_SYS_NICE")
        res = self.agent.set_watched(topics=["/late_chatter"], subscribers=["/relay_late_chatter"])
        self.assertTrue(res.success, res.message)
        relay = self.agent.start(node="relay_late_chatter", param_overrides=[], lease_s=0.0)
        self.assertTrue(relay.success, relay.message)
        try:
            self.assertTrue(wait_for(lambda: self.latest("/late_chatter") is not None, 10.0))
            talker = self.agent.start(node="late_talker", param_overrides=[], lease_s=0.0)
            self.assertTrue(talker.success, talker.message)

            def nice():
                return os.getpriority(os.PRIO_PROCESS, talker.pid)

            try:
                self.assertTrue(wait_for(lambda: nice() == 5, 10.0),
                                "the start boost did not end at the first output (nice %d)"
                                % nice())
                time.sleep(1.0)
                self.assertEqual(nice(), 5, "boosted while it published at 10 Hz")
                # Silent for longer than half its tolerance of 1 s: raised while still silent.
                os.kill(talker.pid, signal.SIGSTOP)
                try:
                    frozen = time.monotonic()
                    self.assertTrue(wait_for(lambda: nice() == -5, 3.0),
                                    "not boosted while silent (nice %d)" % nice())
                    print("late_talker boosted %.2f s into its silence"
                          % (time.monotonic() - frozen))
                    self.assertGreaterEqual(time.monotonic() - frozen, 0.5)
                finally:
                    os.kill(talker.pid, signal.SIGCONT)
                self.assertTrue(wait_for(lambda: nice() == 5, 3.0),
                                "the boost did not end at its next message")
            finally:
                self.agent.stop(node="late_talker", wait=True)
        finally:
            self.agent.stop(node="relay_late_chatter", wait=True)


if __name__ == "__main__":
    rostest.rosrun("anyscale_agent_cpp", "agent_bus_stats", AgentBusStatsTest)
