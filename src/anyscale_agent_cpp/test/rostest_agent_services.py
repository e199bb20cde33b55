#!/usr/bin/python3
"""rostest: node start/stop through the agent's services, refusals, leases, agent shutdown."""
import os
import signal
import subprocess
import sys
import time
import unittest

import psutil
import rosgraph
import rospy
import rostest
from anyscale_msgs.msg import NodeProcess
from diagnostic_msgs.msg import KeyValue

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from agent_test_util import Agent, registered_pid, wait_for  # noqa: E402


def alive(pid):
    """True while the process exists and is not a zombie waiting for a reaper."""
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def sched_idle(pid):
    try:
        return os.sched_getscheduler(pid) == os.SCHED_IDLE
    except ProcessLookupError:
        return False


# A started rospy node's first message: a liveness wait, not a timing assertion. 10 s ran out
# on a host six times slower than usual (2026-11-28: rospy's start-up alone takes seconds there).
FIRST_MESSAGE_S = 30.0
MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "config", "test_model.yaml")


class AgentServicesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("agent_services_test")
        cls.agent = Agent("robot")

    def _start(self, node, lease_s=0.0, overrides=()):
        kv = [KeyValue(key=k, value=v) for k, v in overrides]
        return self.agent.start(node=node, param_overrides=kv, lease_s=lease_s)

    def test_start_stop_rospy_and_roscpp_nodes(self):
        for node in ("talker_py", "talker_cpp"):
            res = self._start(node)
            self.assertTrue(res.success, res.message)
            # Registered with the master under its own name, by the process the agent started.
            self.assertEqual(wait_for(lambda: registered_pid("/" + node), 20.0), res.pid, node)
            self.assertTrue(wait_for(
                lambda: self.agent.node("/" + node).state == NodeProcess.RUNNING, 10.0))
            info = self.agent.node("/" + node)
            self.assertTrue(os.path.exists(info.log_file), info.log_file)
            again = self._start(node)  # already running: its pid, no second process
            self.assertEqual((again.success, again.pid), (True, res.pid), again.message)
            stop = self.agent.stop(node=node, wait=True)
            self.assertTrue(stop.success, stop.message)
            self.assertFalse(alive(res.pid))
            self.assertEqual(self.agent.node("/" + node).state, NodeProcess.EXITED)
            # Clean SIGINT shutdown: the node unregistered itself.
            self.assertTrue(wait_for(lambda: registered_pid("/" + node) is None, 5.0))

    def test_a_paused_node_is_silent_until_a_start_resumes_it(self):
        from std_msgs.msg import String
        res = self._start("talker_py")
        self.assertTrue(res.success, res.message)
        try:
            self.assertTrue(wait_for(
                lambda: self.agent.node("/talker_py").state == NodeProcess.RUNNING, 20.0))
            rospy.wait_for_message("/py_chatter", String, timeout=FIRST_MESSAGE_S)
            paused = self.agent.stop(node="talker_py", wait=True, pause=True)
            self.assertTrue(paused.success, paused.message)
            self.assertEqual(self.agent.node("/talker_py").state, NodeProcess.PAUSED)
            self.assertEqual(psutil.Process(res.pid).status(), psutil.STATUS_STOPPED)
            # Still registered (its XML-RPC API does not answer: it is paused too), publishing
            # nothing.
            self.assertTrue(rosgraph.Master("/agent_test").lookupNode("/talker_py"))
            heard = []
            sub = rospy.Subscriber("/py_chatter", String, heard.append)
            time.sleep(1.0)
            self.assertEqual(heard, [])
            resumed = self._start("talker_py")
            self.assertTrue(resumed.success, resumed.message)
            self.assertIn("resumed", resumed.message)
            self.assertEqual(resumed.pid, res.pid)             # the same process, not a new one
            self.assertEqual(self.agent.node("/talker_py").state, NodeProcess.RUNNING)
            self.assertTrue(wait_for(lambda: heard, 10.0))
            sub.unregister()
            # A paused node stops cleanly: SIGINT reaches it, and it unregisters.
            self.assertTrue(self.agent.stop(node="talker_py", wait=True, pause=True).success)
            self.assertEqual(self.agent.node("/talker_py").state, NodeProcess.PAUSED)
        finally:
            stop = self.agent.stop(node="talker_py", wait=True)
        self.assertTrue(stop.success, stop.message)
        self.assertFalse(alive(res.pid))
        self.assertTrue(wait_for(lambda: registered_pid("/talker_py") is None, 5.0))

    def test_params_remaps_and_overrides(self):
        # The model declares talker_py's state hand-off a pose: those are the overrides it takes.
        res = self._start("talker_py",
                          overrides=[("initial_pose_x", "7.5"), ("initial_pose_a", "2")])
        self.assertTrue(res.success, res.message)
        try:
            self.assertEqual(rospy.get_param("/talker_py/initial_pose_x"), 7.5)
            self.assertEqual(rospy.get_param("/talker_py/initial_pose_a"), 2)
            self.assertEqual(rospy.get_param("/talker_py/rate"), 20.0)
            # $(find) substituted as roslaunch does.
            self.assertTrue(rospy.get_param("/talker_py/text").endswith("anyscale_agent_cpp"))
            self.assertTrue(wait_for(lambda: registered_pid("/talker_py"), 20.0))
            # The model's remap chatter:=/py_chatter is in effect.
            from std_msgs.msg import String
            msg = rospy.wait_for_message("/py_chatter", String, timeout=FIRST_MESSAGE_S)
            self.assertTrue(msg.data.endswith("anyscale_agent_cpp"))
        finally:
            self.agent.stop(node="talker_py", wait=True)
        # Next start without overrides: clear_params drops the old hand-off values.
        res = self._start("talker_py")
        try:
            self.assertEqual(rospy.get_param("/talker_py/rate"), 20.0)
            self.assertFalse(rospy.has_param("/talker_py/initial_pose_x"))
        finally:
            self.agent.stop(node="talker_py", wait=True)

    def test_refusals_say_why(self):
        cases = [
            ("teleop", "not declared"),
            ("../talker_py", "not declared"),
            ("/bin/sh", "not declared"),
            ("talker_py; rm -rf /", "not declared"),
            ("no_binary", "no executable 'does_not_exist'"),
            ("no_package", "package 'anyscale_no_such_package' not found"),
        ]
        for node, why in cases:
            res = self._start(node)
            self.assertFalse(res.success, node)
            self.assertEqual(res.pid, 0)
            self.assertIn(why, res.message, node)
        res = self._start("talker_py", lease_s=-1.0)
        self.assertFalse(res.success)
        self.assertIn("lease_s", res.message)
        res = self._start("talker_py", overrides=[("/abs", "1")])
        self.assertFalse(res.success)
        self.assertIn("not a parameter of the model's state hand-off", res.message)
        self.assertIsNone(registered_pid("/talker_py"))
        stop = self.agent.stop(node="teleop", wait=True)
        self.assertFalse(stop.success)

    def _standby(self, node, agent=None):
        """The waiting standby of `node` (listed after the node itself, which may run)."""
        return next((n for n in (agent or self.agent).list().nodes
                     if n.name == node and n.state == NodeProcess.STANDBY), None)

    def test_warm_standby_becomes_the_node_and_is_prepared_again_at_once_after_a_crash(self):
        standby = wait_for(lambda: self._standby("/warm_talker"), 20.0)
        self.assertTrue(standby, "no warm standby of /warm_talker (launch.warm_start: true)")
        self.assertTrue(alive(standby.pid))
        self.assertIsNone(registered_pid("/warm_talker"))       # not a node yet
        # A standby is not a running node: stop and renew leave it alone.
        self.assertFalse(self.agent.stop(node="warm_talker", wait=True).success)
        self.assertEqual(self.agent.renew(nodes=["warm_talker"], lease_s=2.0).not_running,
                         ["warm_talker"])
        self.assertTrue(alive(standby.pid))

        first_start = self._start("warm_talker")
        self.assertTrue(first_start.success, first_start.message)
        self.assertIn("warm standby", first_start.message)
        self.assertEqual(first_start.pid, standby.pid)
        self.assertEqual(wait_for(lambda: registered_pid("/warm_talker"), 20.0), first_start.pid)
        from std_msgs.msg import String
        # Published on /warm_chatter: the node's remap is in effect.
        rospy.wait_for_message("/warm_chatter", String, timeout=FIRST_MESSAGE_S)
        # ~standby_delay_s (2 s) after the node's start, the next standby waits beside it.
        next_standby = wait_for(lambda: self._standby("/warm_talker"), 15.0)
        self.assertTrue(next_standby, "no new standby while the node runs")
        self.assertNotEqual(next_standby.pid, first_start.pid)
        # The node is listed before its standby.
        self.assertEqual(self.agent.node("/warm_talker").pid, first_start.pid)
        stop = self.agent.stop(node="warm_talker", wait=True)
        self.assertTrue(stop.success, stop.message)
        self.assertFalse(alive(first_start.pid))
        self.assertTrue(alive(next_standby.pid), "stopping the node ended its standby")
        # The next start takes that standby at once.
        second_start = self._start("warm_talker")
        self.assertEqual((second_start.success, second_start.pid), (True, next_standby.pid),
                         second_start.message)
        # Beside a node that never ended unasked here, the standby imports in SCHED_IDLE ...
        beside = wait_for(lambda: self._standby("/warm_talker"), 15.0)
        self.assertTrue(beside, "no new standby while the node runs")
        self.assertTrue(wait_for(lambda: sched_idle(beside.pid), 5.0))
        time.sleep(0.5)
        self.assertTrue(sched_idle(beside.pid), "left SCHED_IDLE though the node never crashed")
        # ... and beside one that crashed here, at the nodes' priority: it may crash again.
        os.kill(second_start.pid, signal.SIGSEGV)
        self.assertTrue(wait_for(
            lambda: self.agent.node("/warm_talker").state == NodeProcess.EXITED, 5.0))
        restart = self._start("warm_talker")
        self.assertEqual((restart.success, restart.pid), (True, beside.pid), restart.message)
        after_crash = wait_for(lambda: self._standby("/warm_talker"), 15.0)
        self.assertTrue(after_crash, "no new standby after the restart")
        self.assertTrue(wait_for(lambda: not sched_idle(after_crash.pid), 5.0),
                        "the standby of a node that crashed here still imports in SCHED_IDLE")
        self.agent.stop(node="warm_talker", wait=True)

    def test_agent_shutdown_leaves_no_process(self):
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            scale = "shutdown_%d" % sig
            agent_proc = subprocess.Popen(
                [self._agent_binary(), "__name:=anyscale_agent_" + scale, "_scale:=" + scale,
                 "_model:=" + MODEL, "_sigint_timeout_s:=3.0"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            try:
                other = Agent(scale)
                pids = []
                for node in ("talker_py", "burner"):
                    res = other.start(node=node, param_overrides=[], lease_s=0.0)
                    self.assertTrue(res.success, res.message)
                    pids.append(res.pid)
                # Not the master scale's agent: its instances run as NAME__SCALE.
                self.assertTrue(wait_for(lambda: registered_pid("/burner__" + scale), 20.0))
                standby = wait_for(lambda: self._standby("/warm_talker", other), 20.0)
                self.assertTrue(standby)
                pids.append(standby.pid)
                children = [c.pid for p in pids for c in psutil.Process(p).children(recursive=True)]
                agent_proc.send_signal(sig)
                agent_proc.wait(timeout=30)
                self.assertTrue(
                    wait_for(lambda: not any(alive(p) for p in pids + children), 15.0),
                    "signal %d left %s" % (sig, [p for p in pids + children if alive(p)]))
            finally:
                if agent_proc.poll() is None:
                    agent_proc.kill()
                    agent_proc.wait()

    def test_a_restarted_master_agent_adopts_the_nodes_a_killed_one_left(self):
        # On the master scale nodes outlive a SIGKILLed agent; the next agent adopts them: listed
        # as running with their pids, started "again" without a second process, stopped.
        scale = "restart"
        state_file = "/tmp/anyscale_agent_test_restart_%d.yaml" % os.getpid()
        self.addCleanup(lambda: os.path.exists(state_file) and os.remove(state_file))
        command = [self._agent_binary(), "__name:=anyscale_agent_" + scale, "_scale:=" + scale,
                   "_is_master:=true", "_model:=" + MODEL, "_sigint_timeout_s:=3.0",
                   "_warm_start:=false", "_state_file:=" + state_file]

        def listed(agent, name):
            try:
                return agent.node(name)
            except (rospy.ServiceException, rospy.ROSException):
                return None  # the killed agent's services stay registered until the next one's

        agents = [subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
        pid = None
        try:
            first = Agent(scale)
            res = first.start(node="talker_cpp", param_overrides=[], lease_s=0.0)
            self.assertTrue(res.success, res.message)
            pid = res.pid
            self.assertEqual(wait_for(lambda: registered_pid("/talker_cpp"), 20.0), pid)
            agents[0].kill()
            agents[0].wait(timeout=30)
            time.sleep(1.0)
            self.assertTrue(alive(pid), "a node of the master scale died with its agent")

            agents.append(subprocess.Popen(command, stdout=subprocess.DEVNULL,
                                           stderr=subprocess.DEVNULL))
            second = Agent(scale)
            node = wait_for(lambda: (n := listed(second, "/talker_cpp"))
                            and n.state == NodeProcess.RUNNING and n, 20.0)
            self.assertTrue(node, "not adopted")
            self.assertEqual(node.pid, pid)
            again = second.start(node="talker_cpp", param_overrides=[], lease_s=0.0)
            self.assertEqual((again.success, again.pid), (True, pid), again.message)
            stop = second.stop(node="talker_cpp", wait=True)
            self.assertTrue(stop.success, stop.message)
            self.assertFalse(alive(pid))
        finally:
            for proc in agents:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()
            if pid and alive(pid):
                os.kill(pid, signal.SIGKILL)

    def test_bad_model_is_a_clear_error(self):
        no_nodes = "/tmp/anyscale_agent_test_no_nodes_%d.yaml" % os.getpid()
        with open(no_nodes, "w") as f:
            f.write("scales: []\n")
        self.addCleanup(os.remove, no_nodes)
        bad_name = "/tmp/anyscale_agent_test_bad_name_%d.yaml" % os.getpid()
        with open(bad_name, "w") as f:
            f.write("nodes: [{name: x, launch: {package: p, type: ../../bin/sh}}]\n")
        self.addCleanup(os.remove, bad_name)
        cases = (("/nonexistent/model.yaml", "/nonexistent/model.yaml: cannot read YAML"),
                 (no_nodes, no_nodes + ": expected a map with a 'nodes' list"),
                 (bad_name, bad_name + ": node 'x': launch.type '../../bin/sh' must be"))
        for model, expected in cases:
            proc = subprocess.run([self._agent_binary(), "__name:=anyscale_agent_bad",
                                   "_scale:=bad", "_model:=" + model],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  timeout=30, text=True)
            self.assertEqual(proc.returncode, 1, proc.stdout)
            self.assertIn(expected, proc.stdout)

    @staticmethod
    def _agent_binary():
        from catkin.find_in_workspaces import find_in_workspaces
        found = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                                   first_matching_workspace_only=True)
        assert found, "anyscale_agent binary not built"
        return found[0]


if __name__ == "__main__":
    rostest.rosrun("anyscale_agent_cpp", "agent_services", AgentServicesTest, sys.argv)
