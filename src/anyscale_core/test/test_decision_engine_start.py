"""The decision engine starting the system: every node on the robot (the paper's initial
configuration), a restarted engine adopting what runs, no moves until the initial configuration
is up, and starts that carry the node's last pose (state hand-off)."""
from anyscale_core.allocators import make_allocator
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import StartNode, pose_handoff_params

from decision_reports import HEALTHY, PAPER, remote, reports


def test_initial_configuration_starts_everything_on_the_robot(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), PAPER)
    result = e.adopt_or_start(reports(0.0), 0.0)
    assert sorted(a.node for a in result.actions) == sorted(testbed_ch.node_names)
    assert all(isinstance(a, StartNode) and a.scale == "robot" and a.lease_s == 0
               for a in result.actions)


def test_restarted_engine_adopts_what_runs(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), PAPER)
    running = reports(0.0, laptop_running=("amcl",))
    running["robot"] = running["robot"].__class__(
        "robot", 0.0, 40.0, 2.0, {n: 5.0 for n in testbed_ch.node_names if n != "amcl"}, HEALTHY)
    result = e.adopt_or_start(running, 0.0)
    assert result.actions == []
    assert {ev.kind for ev in result.events} == {"adopt"}
    assert remote(e) == ["amcl"]


def test_no_moves_while_the_initial_configuration_comes_up(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), PAPER)
    e.adopt_or_start(reports(0.0), 0.0)
    for t in (1.0, 2.0, 3.0):
        assert e.tick(reports(t), t, moves_allowed=False).actions == []
    assert remote(e) == []
    e.tick(reports(4.0), 4.0)
    assert remote(e) == ["amcl"]                     # moves start with the first allowed tick


def test_start_carries_the_last_pose(engine):
    engine.observe_handoff("amcl", pose_handoff_params(3.0, 4.0, 1.5, 0.1, 0.1, 0.05))
    start = engine.tick(reports(1.0), 1.0).actions[0]
    assert dict(start.param_overrides)["initial_pose_x"] == 3.0
    assert dict(start.param_overrides)["initial_pose_a"] == 1.5
    # The wrapper asks again when it sends the start, for the newest pose.
    engine.observe_handoff("amcl", pose_handoff_params(3.2, 4.0, 1.5, 0.1, 0.1, 0.05))
    assert dict(engine.handoff_overrides("amcl"))["initial_pose_x"] == 3.2
    assert engine.handoff_overrides("ar_recognition") == ()       # no state_handoff
