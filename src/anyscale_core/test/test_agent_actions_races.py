"""The decision node's actions where a tolerance bench run found them wrong: a registration
check that took a paused instance for a ghost, and a handover that fell back to an instance out
of reach. AgentActions (agent_actions_ros.py) on a stand-in for the decision node, with the
master calls and the agents replaced."""
import threading
import types

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
