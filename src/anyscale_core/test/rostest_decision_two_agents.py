#!/usr/bin/python3
"""rostest: the decision node with two agents on loopback moves a stock topic_tools relay to the
laptop, never runs two /relay processes, brings it back when the laptop's agent is SIGKILLed,
starts it again when it crashes, and `anyscale top --once` shows where it runs."""
import math
import os
import signal
import subprocess
import threading
import time
import unittest

import psutil
import rosgraph
import rospy
import rostest
from anyscale_msgs.msg import Mapping, MigrationEvent, NodeProcess, ScaleStatus
from anyscale_msgs.srv import ListNodes
from std_msgs.msg import String

from anyscale_core.agent_client import call_with_timeout, registered_pid
from anyscale_core.polling import wait_for

ALIVE = (NodeProcess.STARTING, NodeProcess.RUNNING, NodeProcess.STOPPING)


def executable(name):
    """A program of anyscale_core in the workspace (rosrun is not installed here)."""
    from catkin.find_in_workspaces import find_in_workspaces
    return find_in_workspaces(["libexec"], project="anyscale_core", path=name,
                              first_matching_workspace_only=True)[0]


# A planned move starts the new relay before it stops the old one (make before break): two
# relays, and two publishers of /chatter_relay, for this long at most around its MIGRATE event.
HANDOVER_OVERLAP_S = 5.0
# The laptop's agent (no quota on loopback: this machine's CPU) this busy over its last 20
# statuses (10 s): the machine is saturated and the relay rightly has no room on the laptop.
SATURATED_PERCENT = 95.0


def saturation(laptop_cpu):
    """Why a failed move says nothing of the engine, from an independent measurement only: the
    median of the laptop agent's last 20 CPU figures (ScaleStatus.cpu_percent) at or above
    SATURATED_PERCENT; None otherwise. What the engine reported (an "over capacity" MIGRATE_BACK)
    is the output under test and never decides it."""
    recent = sorted(laptop_cpu[-20:])
    if recent and recent[len(recent) // 2] >= SATURATED_PERCENT:
        return (f"machine saturated: laptop CPU median {recent[len(recent) // 2]:.0f} % over "
                "the last 10 s, no room for the relay")
    return None


def is_relay_name(arg):
    """/relay on the master scale, /relay__SCALE elsewhere."""
    return arg == "__name:=relay" or arg.startswith("__name:=relay__")


def relay_processes():
    """pids of live processes started as the node relay on this machine (both scales)."""
    pids = []
    for p in psutil.process_iter(["cmdline", "status"]):
        if p.info["status"] != psutil.STATUS_ZOMBIE and any(map(is_relay_name,
                                                                p.info["cmdline"] or [])):
            pids.append(p.pid)
    return pids


def relay_publishers(master):
    pubs = [p for t, p in master.getSystemState()[0] if t == "/chatter_relay"]
    return pubs[0] if pubs else []


def agent_relays(scale):
    """pids of /relay that an agent lists alive; None if the agent does not answer."""
    try:
        reply = call_with_timeout(
            rospy.ServiceProxy(f"/anyscale/{scale}/list_nodes", ListNodes), 1.0)
    except Exception:  # noqa: BLE001 - a dead agent
        return None
    return {n.pid for n in reply.nodes if n.name == "/relay" and n.state in ALIVE}


class Sampler(threading.Thread):
    """Samples, until stopped, the processes of the relay, the agents' lists and the master's
    publishers of /chatter_relay; records every moment with more than one."""

    def __init__(self):
        super().__init__(daemon=True)
        self.running = True
        self.samples = 0
        self.violations = []
        self.master = rosgraph.Master("/decision_test_sampler")

    def run(self):
        while self.running:
            procs = relay_processes()
            # robot, laptop, robot again: a pid seen on the robot before and after the
            # laptop's answer existed while the laptop answered (no false alarm from a move
            # between two calls).
            r1, lap, r2 = agent_relays("robot"), agent_relays("laptop"), agent_relays("robot")
            both = (r1 or set()) & (r2 or set())
            pubs = relay_publishers(self.master)
            # A killed instance stays registered until the decision node purges it: only
            # publishers that answer could publish.
            pubs = [p for p in pubs if registered_pid(p, "/decision_test_sampler") is not None]
            if len(procs) > 1 or (both and lap) or len(pubs) > 1:
                self.violations.append((time.monotonic(), procs, r1, lap, r2, pubs))
            self.samples += 1
            time.sleep(0.1)

    def unexplained(self, handovers):
        """Moments with two relays that no planned move's overlap explains."""
        return [v for v in self.violations
                if not any(abs(v[0] - t) <= HANDOVER_OVERLAP_S for t in handovers)]


class DecisionTwoAgentsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("decision_two_agents_test")
        cls.model = rospy.get_param("~model")

    def start_decision(self, *extra):
        proc = subprocess.Popen(
            [executable("decision_node"), "__name:=anyscale_decision", "_model:=" + self.model,
             "_period_s:=1.0", "_lease_s:=3.0", "_status_timeout_s:=1.5",
             "_startup_grace_s:=3.0", "_adopt_wait_s:=10.0", *extra],
            start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.addCleanup(self.stop_decision, proc)
        return proc

    @staticmethod
    def stop_decision(proc):
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()

    def test_a_bad_model_is_one_fatal_line(self):
        proc = self.start_decision("_model:=/nonexistent/model.yaml", "_period_s:=0.5")
        out, _ = proc.communicate(timeout=60)
        self.assertEqual(proc.returncode, 1, out)
        self.assertNotIn("Traceback", out)
        fatal = [ln for ln in out.splitlines() if "FATAL" in ln]
        self.assertEqual(len(fatal), 1, out)
        self.assertIn("/nonexistent/model.yaml", fatal[0])

    def subscribe(self):
        self.events, self.mappings, self.relayed, self.laptop_cpu = [], [], [], []
        self.handovers = []     # when each planned move's MIGRATE event arrived
        self.callers = set()    # instances that published /chatter_relay
        rospy.Subscriber("/anyscale/status", ScaleStatus, lambda m: m.scale == "laptop" and
                         self.laptop_cpu.append(m.cpu_percent), queue_size=20)
        rospy.Subscriber("/anyscale/events", MigrationEvent, self.on_event, queue_size=100)
        rospy.Subscriber("/anyscale/mapping", Mapping, self.mappings.append, queue_size=10)
        rospy.Subscriber("/chatter_relay", String, self.on_relayed, queue_size=100)
        self.assertTrue(wait_for(lambda: agent_relays("robot") is not None and
                                 agent_relays("laptop") is not None, 30.0), "agents not up")
        self.sampler = Sampler()
        self.sampler.start()
        self.addCleanup(setattr, self.sampler, "running", False)

    def on_event(self, msg):
        self.events.append(msg)
        if msg.kind == MigrationEvent.MIGRATE:
            self.handovers.append(time.monotonic())

    def on_relayed(self, msg):
        self.relayed.append(time.monotonic())
        self.callers.add(msg._connection_header["callerid"])

    def event(self, kind, node, to_scale):
        return next((e for e in self.events
                     if e.kind == kind and e.node == node and e.to_scale == to_scale), None)

    def mapping_of(self, node):
        return {a.node: a.scale for a in self.mappings[-1].assignments}.get(node) \
            if self.mappings else None

    def skip_if_saturated(self):
        """Both scales share this machine's CPU: when something else saturates it, the laptop
        is (correctly) over capacity and the relay comes back at once. That is the engine's
        CPU constraint at work, not this test's subject; the agent's CPU figures tell it."""
        why = saturation(self.laptop_cpu)
        if why:
            self.skipTest(why)

    def flowing(self, seconds=1.0):
        return bool(self.relayed) and time.monotonic() - self.relayed[-1] < seconds

    def test_b_relay_moves_out_and_back(self):
        t0 = time.monotonic()
        self.subscribe()
        decision = self.start_decision()
        # Its output would fill the pipe: read it away (shown by rostest on failure anyway).
        threading.Thread(target=lambda: [print(ln, end="") for ln in decision.stdout],
                         daemon=True).start()
        # (a) Everything starts under the robot's agent.
        for node in ("talker", "listener", "relay", "relay_listener"):
            self.assertTrue(wait_for(lambda n=node: self.event(MigrationEvent.START, n, "robot"),
                                     40.0), f"no START of {node} on robot: {self.events}")
            start = self.event(MigrationEvent.START, node, "robot")
            self.assertTrue(start.success, start.reason)
            self.assertTrue(math.isfinite(start.duration_s))
        self.assertTrue(all(a.scale == "robot" for a in self.mappings[0].assignments),
                        self.mappings[0])
        # (b) The relay moves to the laptop and /chatter_relay keeps flowing.
        try:
            moved = wait_for(lambda: self.event(MigrationEvent.MIGRATE, "relay", "laptop"), 30.0)
            self.assertTrue(moved, f"relay never migrated: {self.events}")
            self.assertTrue(moved.success and moved.reason, moved)
            self.assertTrue(wait_for(lambda: agent_relays("laptop"), 10.0))
            self.assertEqual(self.mapping_of("relay"), "laptop")
            self.assertEqual(registered_pid("/relay__laptop", "/decision_test"),
                             next(iter(agent_relays("laptop"))))
            self.assertTrue(wait_for(self.flowing, 10.0), "/chatter_relay silent after the move")
            # Make before break: the robot's relay is stopped once the laptop's published.
            self.assertTrue(wait_for(lambda: "/relay__laptop" in self.callers, 5.0), self.callers)
            self.assertTrue(wait_for(lambda: not agent_relays("robot"), 10.0),
                            "the robot's relay still runs after the move")
            time.sleep(3.0)       # a few lease renewals: the relay stays out
            self.assertTrue(self.flowing(), "/chatter_relay stopped while the relay ran remotely")
            self.assertEqual(self.mapping_of("relay"), "laptop")
            # (d) `anyscale top --once` shows the relay and where it runs.
            top = subprocess.run([executable("anyscale"), "top", "--once"],
                                 capture_output=True, text=True, timeout=60)
            self.assertEqual(top.returncode, 0, top.stderr)
            lines = [ln for ln in top.stdout.splitlines() if ln.split()[:1] == ["relay"]]
            self.assertTrue(lines and "laptop" in lines[0], top.stdout)
        except AssertionError:
            self.skip_if_saturated()
            raise
        print(top.stdout)
        # (c) SIGKILL the laptop's agent: the relay is back on the robot.
        agent_pid = registered_pid("/anyscale_agent_laptop", "/decision_test")
        self.assertTrue(agent_pid)
        killed = time.monotonic()
        os.kill(agent_pid, signal.SIGKILL)
        back = wait_for(lambda: self.event(MigrationEvent.MIGRATE_BACK, "relay", "robot"), 15.0)
        self.assertTrue(back, f"relay not migrated back: {self.events}")
        self.assertTrue(back.success and back.reason, back)
        self.assertTrue(wait_for(lambda: agent_relays("robot"), 5.0))
        back_at = time.monotonic() - killed
        self.assertLess(back_at, 1.5 + 10.0)
        self.assertEqual(self.mapping_of("relay"), "robot")
        self.assertTrue(wait_for(self.flowing, 10.0), "/chatter_relay silent after coming back")
        # The killed laptop relay's registration is removed (no ghost publisher).
        master = rosgraph.Master("/decision_test")
        self.assertTrue(wait_for(lambda: relay_publishers(master) == ["/relay"], 10.0),
                        relay_publishers(master))
        # A restarted decision node adopts the relay instead of starting another one.
        relay_pid = registered_pid("/relay", "/decision_test")
        self.stop_decision(decision)
        self.events.clear()
        decision = self.start_decision("_adopt_wait_s:=3.0")   # the laptop stays silent
        threading.Thread(target=lambda: [print(ln, end="") for ln in decision.stdout],
                         daemon=True).start()
        self.assertTrue(wait_for(lambda: self.event(MigrationEvent.ADOPT, "relay", "robot"),
                                 30.0), f"relay not adopted: {self.events}")
        time.sleep(2.0)
        self.assertFalse([e for e in self.events if e.kind == MigrationEvent.START], self.events)
        self.assertEqual(registered_pid("/relay", "/decision_test"), relay_pid)
        # (e) The relay crashes where it runs: started again there, like roslaunch's respawn.
        os.kill(relay_pid, signal.SIGSEGV)
        restart = wait_for(lambda: self.event(MigrationEvent.RESTART, "relay", "robot"), 20.0)
        self.assertTrue(restart, f"relay not restarted: {self.events}")
        self.assertTrue(restart.success and "signal 11" in restart.reason, restart)
        self.assertNotIn(registered_pid("/relay", "/decision_test"), (None, relay_pid))
        self.assertTrue(wait_for(self.flowing, 10.0), "/chatter_relay silent after the restart")
        self.sampler.running = False
        self.sampler.join(5.0)
        self.assertGreater(self.sampler.samples, 20)
        self.assertEqual(self.sampler.unexplained(self.handovers), [],
                         "two relays at once, outside a planned move's overlap")
        print(f"[decision_two_agents] migrate {moved.duration_s:.2f} s, migrate back "
              f"{back.duration_s:.2f} s ({back.reason}); back on the robot {back_at:.1f} s after "
              f"the SIGKILL; {self.sampler.samples} samples; test {time.monotonic() - t0:.0f} s")


if __name__ == "__main__":
    rostest.rosrun("anyscale_core", "decision_two_agents", DecisionTwoAgentsTest)
