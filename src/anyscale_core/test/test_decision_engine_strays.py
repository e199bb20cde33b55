"""The decision engine's strays: an instance reported running where the mapping does not place
its node, with nothing under way for the node, is stopped (paused at home, for a node declared
pause_at_home). The fault soak's case: the robot's agent killed while AMCL moved out, the pause
of its robot instance refused, the agent's successor adopting the instance as running."""
from dataclasses import replace

from anyscale_core.decision_types import StopNode

from decision_reports import reports


def strays(result):
    return [a for a in result.actions if isinstance(a, StopNode) and a.stray]


def robot_running(now, nodes, **kwargs):
    """reports(now) whose robot report shows `nodes` running there."""
    out = reports(now, **kwargs)
    out["robot"] = replace(out["robot"], running={n: 20.0 for n in nodes})
    return out


def amcl_out(engine):
    """AMCL moved to the laptop at t = 1, its robot instance's pause answered at 1.5 s."""
    assert engine.tick(reports(1.0), 1.0).events[0].node == "amcl"
    engine.stop_answered("amcl", 1.5)


def test_an_instance_whose_pause_did_not_get_through_is_paused(engine):
    amcl_out(engine)
    result = engine.tick(robot_running(2.0, ["amcl"]), 2.0)
    assert strays(result) == [StopNode("amcl", "robot", pause=True, stray=True)]


def test_a_report_from_before_the_stop_was_answered_does_not_count(engine):
    amcl_out(engine)
    assert strays(engine.tick(robot_running(1.4, ["amcl"]), 1.6)) == []


def test_a_node_with_an_action_under_way_is_left_alone(engine):
    amcl_out(engine)
    assert strays(engine.tick(robot_running(2.0, ["amcl"]), 2.0, acting={"amcl"})) == []
    assert strays(engine.tick(robot_running(2.5, ["amcl"]), 2.5, starting={"amcl"})) == []


def test_a_stale_report_does_not_count(engine):
    amcl_out(engine)
    stale = robot_running(2.0, ["amcl"])
    assert strays(engine.tick(stale, 2.0 + engine.params.status_timeout_s + 0.1)) == []


def test_where_the_mapping_places_the_node_nothing_is_a_stray(engine):
    amcl_out(engine)
    result = engine.tick(reports(2.0, laptop_running=["amcl"]), 2.0)
    assert strays(result) == []


def test_a_remote_instance_left_after_a_return_is_stopped_once_the_scale_is_in_reach(engine):
    amcl_out(engine)
    engine.tick(reports(2.0), 2.0)                                   # AR out
    engine.tick(reports(3.0, bandwidth=3.0), 3.0)                    # AR home on a weak link
    engine.stop_answered("ar_recognition", 3.5)
    out_of_reach = engine.tick(reports(4.0, laptop=False), 4.0)
    assert [s for s in strays(out_of_reach) if s.node == "ar_recognition"] == []
    result = engine.tick(reports(5.0, bandwidth=3.0, laptop_running=["ar_recognition"]), 5.0)
    assert [s for s in strays(result) if s.node == "ar_recognition"] == [
        StopNode("ar_recognition", "laptop", stray=True)]


def test_a_node_moved_in_the_same_tick_is_left_to_its_move(engine):
    # AMCL's robot instance shows up running just as a link loss brings AMCL home: the return
    # resumes (starts) it there; pausing it as a stray would silence it.
    amcl_out(engine)
    result = engine.tick(robot_running(2.0, ["amcl"], laptop=False), 2.0)
    assert any(e.node == "amcl" and e.to_scale == "robot" for e in result.events)
    assert [a for a in strays(result) if a.node == "amcl"] == []


def test_strays_are_stopped_while_the_initial_configuration_comes_up(engine):
    amcl_out(engine)
    result = engine.tick(robot_running(2.0, ["amcl"]), 2.0, moves_allowed=False)
    assert strays(result) == [StopNode("amcl", "robot", pause=True, stray=True)]
