#!/usr/bin/python3
"""rostest: a watched topic is counted as soon as the agent runs the node that the decision
node names as its subscriber, with no help from the master's graph (its poll is held off for
the whole test); and one whose named subscriber does not run here is not counted."""
import os
import sys
import unittest

import rospy
import rostest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from agent_test_util import Agent, wait_for  # noqa: E402


def rate_of(status, topic):
    return next((t.rate_hz for t in status.topics if t.topic == topic), None)


class AgentWatchListTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("agent_watch_list_test")
        cls.agent = Agent("robot")

    def test_the_input_of_a_node_run_here_is_counted_without_the_graph(self):
        res = self.agent.set_watched(topics=["/hz10", "/unread"], subscribers=["/relay_hz10", ""])
        self.assertTrue(res.success, res.message)
        self.assertTrue(wait_for(lambda: self.agent.statuses, 10.0))
        self.assertIsNone(rate_of(self.agent.statuses[-1], "/hz10"))   # nothing here reads it yet
        started = self.agent.start(node="relay_hz10", param_overrides=[], lease_s=0.0)
        self.assertTrue(started.success, started.message)
        try:
            # The renewal thread runs about once a second; the 2 s window then fills.
            self.assertTrue(
                wait_for(lambda: (rate_of(self.agent.statuses[-1], "/hz10") or 0.0) > 5.0, 15.0),
                "no rate for /hz10 while its subscriber runs here")
            self.assertIsNone(rate_of(self.agent.statuses[-1], "/unread"))
        finally:
            self.agent.stop(node="relay_hz10", wait=True)
        # Once the node is gone, the agent lets go of its input.
        self.assertTrue(wait_for(lambda: rate_of(self.agent.statuses[-1], "/hz10") is None, 10.0))

    def test_mismatched_lists_are_refused_with_the_reason(self):
        res = self.agent.set_watched(topics=["/hz10", "/other"], subscribers=["/relay_hz10"])
        self.assertFalse(res.success)
        self.assertIn("1 subscribers for 2 topics", res.message)
        res = self.agent.set_watched(topics=["/hz10"], subscribers=["not a name"])
        self.assertFalse(res.success)
        self.assertIn("subscriber", res.message)


if __name__ == "__main__":
    rostest.rosrun("anyscale_agent_cpp", "agent_watch_list", AgentWatchListTest)
