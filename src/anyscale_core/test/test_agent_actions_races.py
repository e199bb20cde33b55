"""The decision node's actions where test bed runs found them wrong: a registration check
that took a paused instance for a ghost, a handover that fell back to an instance out of reach,
a stray to stop only while its agent still shows it running, and a watch list a restarted
agent lost. AgentActions (agent_actions_ros.py) on a stand-in for the decision node, with the
master calls and the agents replaced."""
import threading
import types

from anyscale_msgs.msg import NodeProcess, ScaleStatus

from anyscale_core import agent_actions_ros
from anyscale_core.agent_actions_ros import AgentActions
from anyscale_core.decision_types import StopNode
from anyscale_core.handover_ros import TIMED_OUT


class Node(AgentActions):
    """What AgentActions uses of DecisionNode: AR recognition on the laptop, its robot
    instance about to be paused (launch.pause_at_home)."""

    def __init__(self, model, link_up=None):
        self.model = model
        self.lock = threading.Lock()
        self.handing_over, self.pausing, self.reports, self.statuses = set(), {}, {}, {}
        self.link_up = link_up or {}
        self.caller_id = "/anyscale_decision"
        self.params = types.SimpleNamespace(handover_timeout_s=20.0)
        mapping = {n: "robot" for n in model.node_names}
        mapping["ar_recognition"] = "laptop"
        self.failed, self.stopped, self.published = [], [], []
        self.engine = types.SimpleNamespace(
            mapping=lambda: dict(mapping),
            move_failed=lambda *args: self.failed.append(args))

    def _stop(self, node, scale, best_effort=False, pause=False):
        self.stopped.append((node, scale))

    def _publish_event(self, *args):
        self.published.append(args)


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
    monkeypatch.setattr(reachable, "_publish_mapping", lambda: None, raising=False)
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
