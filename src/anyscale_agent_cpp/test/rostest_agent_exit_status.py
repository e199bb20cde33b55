#!/usr/bin/python3
"""rostest: a node that ends unasked (a crash) is in the agent's status within a supervision
period of its end, so the decision node restarts it without waiting for the next sample."""
import os
import signal
import sys
import time
import unittest

import rospy
import rostest
from anyscale_msgs.msg import NodeProcess

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from agent_test_util import Agent, wait_for  # noqa: E402

# The agent samples every 2 s here (agent_exit_status.test) and supervises every 0.1 s.
WITHIN_S = 0.5


def shows_exited(status, name):
    return any(n.name == name and n.state == NodeProcess.EXITED for n in status.nodes)


class AgentExitStatusTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("agent_exit_status_test")
        cls.agent = Agent("robot")

    def test_a_crash_is_reported_at_once(self):
        for attempt in range(2):
            res = self.agent.start(node="talker_cpp", param_overrides=[], lease_s=0.0)
            self.assertTrue(res.success, res.message)
            self.assertTrue(wait_for(
                lambda: self.agent.node("/talker_cpp").state == NodeProcess.RUNNING, 20.0))
            # Right after a periodic sample: the next is 2 s away.
            seen = len(self.agent.statuses)
            self.assertTrue(wait_for(lambda: len(self.agent.statuses) > seen, 5.0))
            killed_at = time.monotonic()
            os.kill(res.pid, signal.SIGSEGV)
            first = wait_for(lambda: next((time.monotonic()
                                           for s in list(self.agent.statuses)[seen:]
                                           if shows_exited(s, "/talker_cpp")), None), 5.0)
            self.assertIsNotNone(first, "no status showed the crash")
            self.assertLess(first - killed_at, WITHIN_S, f"attempt {attempt + 1}")
            node = self.agent.node("/talker_cpp")
            self.assertEqual(node.exit_signal, signal.SIGSEGV)


if __name__ == "__main__":
    rostest.rosrun("anyscale_agent_cpp", "agent_exit_status", AgentExitStatusTest)
