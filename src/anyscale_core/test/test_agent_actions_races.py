"""The decision node's actions where test bed runs found them wrong: a registration check
that took a paused instance for a ghost, a handover that fell back to an instance out of reach,
a stray to stop only while its agent still shows it running, and a watch list a restarted
agent lost. AgentActions (agent_actions_ros.py) with the master calls, the agents and the engine
replaced."""
import ast
import inspect
import threading
import types

from anyscale_msgs.msg import NodeProcess, ScaleStatus
from anyscale_msgs.srv import StartNodeResponse as StartReply

from anyscale_core import agent_actions_ros
from anyscale_core.agent_actions_ros import AgentActions
from anyscale_core.decision_types import StartNode, StopNode
from anyscale_core.handover_ros import TIMED_OUT


class Node(AgentActions):
    """AgentActions with the agents and the engine replaced, its stops, failed moves and events
    recorded: AR recognition on the laptop, its robot instance about to be paused
    (launch.pause_at_home)."""

    def __init__(self, model, link_up=None):
        self.failed, self.stopped, self.published = [], [], []
        mapping = {n: "robot" for n in model.node_names}
        mapping["ar_recognition"] = "laptop"
        engine = types.SimpleNamespace(mapping=lambda: dict(mapping),
                                       move_failed=lambda *args: self.failed.append(args))
        super().__init__(model, types.SimpleNamespace(handover_timeout_s=20.0), engine,
                         threading.Lock(), agents=None, reports={}, statuses={},
                         publish_event=lambda *args: self.published.append(args),
                         publish_mapping=lambda: None, caller_id="/anyscale_decision")
        self.link_up = link_up or {}

    def _stop(self, node, scale, best_effort=False, pause=False):
        self.stopped.append((node, scale))


def test_an_instance_paused_while_its_registration_is_checked_is_no_ghost(testbed,
                                                                          monkeypatch):
    node = Node(testbed)
    names = node._ghost_candidates()
    assert "/ar_recognition" in names            # not yet paused: a candidate

    def pings(master, candidates, caller_id, timeout_s):
        # The handover that had just ended pauses the robot instance while it is pinged: it
        # stops answering, and the pause is under way by the time the pings are done.
        node.pausing["/ar_recognition"] = ("robot", None)
        return ["/ar_recognition", "/ekf__laptop"]
    purged = []
    monkeypatch.setattr(agent_actions_ros, "dead_registrations", pings)
    monkeypatch.setattr(agent_actions_ros, "purge", lambda master, dead: purged.append(dead))
    monkeypatch.setattr(agent_actions_ros.rosgraph, "Master", lambda caller_id: object())
    node._purge(names)
    assert purged == [["/ekf__laptop"]]


def test_a_handover_back_whose_old_instance_is_out_of_reach_keeps_the_new_one(testbed,
                                                                              monkeypatch):
    monkeypatch.setattr(agent_actions_ros, "wait_for_output", lambda *args: TIMED_OUT)
    watch = types.SimpleNamespace(close=lambda: None)
    stop = StopNode("ar_recognition", "laptop", after_output_on="robot")
    cut_off = Node(testbed, link_up={"laptop": False})
    cut_off._overlap("ar_recognition", stop, watch, pid=42)
    assert cut_off.stopped == [] and cut_off.failed == [] and cut_off.published == []
    # With the old instance in reach, the new one that never published is stopped and the
    # node stays where it was.
    reachable = Node(testbed, link_up={"laptop": True})
    reachable._overlap("ar_recognition", stop, watch, pid=42)
    assert reachable.stopped == [("ar_recognition", "robot")]
    assert [args[:3] for args in reachable.failed] == [("ar_recognition", "laptop", "robot")]


def status(*processes):
    """A ScaleStatus of the robot's agent showing (name, state) processes."""
    return ScaleStatus(scale="robot", nodes=[NodeProcess(name=n, state=s) for n, s in processes])


def test_a_stray_is_stopped_only_while_its_agent_still_shows_it_running(testbed, monkeypatch):
    monkeypatch.setattr(agent_actions_ros.rospy, "logwarn", lambda *args: None)
    node = Node(testbed)
    stray = StopNode("ar_recognition", "robot", pause=True, stray=True)
    node.statuses["robot"] = status(("/ar_recognition", NodeProcess.PAUSED))
    node._stop_stray("ar_recognition", stray)          # paused meanwhile: nothing to do
    assert node.stopped == []
    node.statuses["robot"] = status(("/ar_recognition", NodeProcess.RUNNING))
    node._stop_stray("ar_recognition", stray)
    assert node.stopped == [("ar_recognition", "robot")]


def test_a_stray_where_the_node_is_mapped_again_is_left_running(testbed, monkeypatch):
    node = Node(testbed)
    node.statuses["robot"] = status(("/amcl", NodeProcess.RUNNING))
    node._stop_stray("amcl", StopNode("amcl", "robot", pause=True, stray=True))
    assert node.stopped == []


def report(at, topics, running):
    return types.SimpleNamespace(received_at=at, topic_rates={t: 5.0 for t in topics},
                                 running={n: 1.0 for n in running})


def test_a_watch_list_is_lost_when_a_later_report_lacks_a_topic_its_subscriber_runs_for():
    watched = [("/amcl_pose", "/ekf"), ("/scan", "/amcl")]
    lost = AgentActions._watch_list_lost
    sent = 10.0
    assert lost(report(11.5, ["/scan"], ["ekf", "amcl"]), watched, sent)
    # too soon after the list was sent for the agent to count the topic
    assert not lost(report(10.5, ["/scan"], ["ekf", "amcl"]), watched, sent)
    # the subscriber does not run there (yet): the agent would not count it
    assert not lost(report(11.5, ["/scan"], ["amcl"]), watched, sent)
    assert not lost(report(11.5, ["/scan", "/amcl_pose"], ["ekf", "amcl"]), watched, sent)


def test_a_move_out_refused_for_capacity_leaves_the_node_running_where_it_was(
        testbed, monkeypatch):
    """Make before break: the new instance's start comes first, and a shared scale that
    refuses it leaves the old one alone; the engine hears of the refusal before the node is
    put back (its back-off), then keeps it where it runs."""
    monkeypatch.setattr(agent_actions_ros, "OutputWatch", lambda *args: types.SimpleNamespace(
        close=lambda: None))
    monkeypatch.setattr(agent_actions_ros.rospy, "logerr", lambda *args: None)
    monkeypatch.setattr(agent_actions_ros.rospy.Time, "now", lambda: None)
    node = Node(testbed)
    node.params.handover_messages = 3
    calls = []
    node.agents = types.SimpleNamespace(start=lambda *args: calls.append(args) or StartReply(
        success=False, pid=0, message="refused: /amcl: laptop full: CPU 72 % held by 2 robots "
        "+ 36 % asked > 100 %", scale_full=True, cpu_free_percent=28.0, memory_free_mb=900.0))
    node.starting, node.handing_over = {("amcl", "laptop")}, set()
    node.engine.handoff_overrides = lambda name: ()
    node.engine.capacity_refused = lambda *args: calls.append(("refused",) + args) or []
    node.engine.move_failed = lambda *args: calls.append(("move_failed",) + args[:3])
    start = StartNode("amcl", "laptop", (), 3.0, 36.0, 120.0)
    stop = StopNode("amcl", "robot", after_output_on="laptop")
    event = types.SimpleNamespace(from_scale="robot")
    node._execute_move("amcl", [start, stop], event, None, 0.0)
    assert calls[0][:6] == ("laptop", "amcl", [], 3.0, 36.0, 120.0)   # what it asks for
    assert calls[1][:5] == ("refused", "amcl", "laptop", 28.0, 900.0)
    assert calls[2] == ("move_failed", "amcl", "robot", "laptop")
    assert node.stopped == [] and node.handing_over == set()
    assert node.published[0][0] == "failed" and "laptop full" in node.published[0][4]


def test_agent_actions_uses_only_what_its_init_declares_or_its_class_defines():
    """An object handed what it needs, not a mixin reaching into the decision node."""
    source = inspect.getsource(agent_actions_ros)
    [cls] = [n for n in ast.walk(ast.parse(source))
             if isinstance(n, ast.ClassDef) and n.name == "AgentActions"]
    defined = {f.name for f in cls.body if isinstance(f, ast.FunctionDef)}
    [init] = [f for f in cls.body if isinstance(f, ast.FunctionDef) and f.name == "__init__"]
    declared = {t.attr for n in ast.walk(init) if isinstance(n, (ast.Assign, ast.AnnAssign))
                for target in (n.targets if isinstance(n, ast.Assign) else [n.target])
                for t in ast.walk(target) if isinstance(t, ast.Attribute)}
    used = {n.attr for n in ast.walk(cls) if isinstance(n, ast.Attribute)
            and isinstance(n.value, ast.Name) and n.value.id == "self"}
    assert used - declared - defined == set()
