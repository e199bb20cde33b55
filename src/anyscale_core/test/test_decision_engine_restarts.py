"""The decision engine restarting nodes that ended unasked: where they ran (remote ones with a
lease and their last state), at once and then backing off, at once again after a healthy run,
also while the initial configuration comes up, never on a scale out of reach."""
import dataclasses

import pytest

from anyscale_core.allocators import make_allocator
from anyscale_core.characterisation import characterise
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams, StartNode, pose_handoff_params
from anyscale_core.restart_backoff import BackoffParams, RestartBackoff

from decision_reports import PAPER, reports


def test_a_node_that_failed_where_it_runs_is_started_there_again(engine, testbed_ch):
    engine.tick(reports(1.0), 1.0)                         # amcl to the laptop
    r = reports(9.0, laptop_running=("amcl",))
    r["robot"] = dataclasses.replace(r["robot"], ended={"ekf": "signal 11"})
    result = engine.tick(r, 9.0)
    assert ("restart", "ekf", "robot", "robot") in [(e.kind, e.node, e.from_scale, e.to_scale)
                                                    for e in result.events]
    assert StartNode("ekf", "robot", (), 0.0, 5.0, 55.0) in result.actions
    assert "ended on robot: signal 11" in [e.reason for e in result.events if e.node == "ekf"]
    # A remote node is started again on its remote scale, with a lease and its last state.
    plain = dataclasses.replace(testbed_ch.model.node("amcl").launch, pause_at_home=False)
    e = engine_with_amcl_launch(testbed_ch, plain)
    e.tick(reports(1.0), 1.0)
    e.observe_handoff("amcl", pose_handoff_params(1.0, 2.0, 0.5, 0.1, 0.1, 0.05, 8.0))
    r = reports(10.0)
    r["laptop"] = dataclasses.replace(r["laptop"], ended={"amcl": "exit code 1"})
    restart = [a for a in e.tick(r, 10.0).actions if isinstance(a, StartNode) and a.node == "amcl"]
    assert [(a.node, a.scale, a.lease_s) for a in restart] == [("amcl", "laptop", 3.0)]
    assert dict(restart[0].param_overrides)["initial_pose_x"] == 1.0


def engine_with_amcl_launch(testbed_ch, launch):
    nodes = [dataclasses.replace(n, launch=launch) if n.name == "amcl" else n
             for n in testbed_ch.model.nodes]
    ch = characterise(dataclasses.replace(testbed_ch.model, nodes=nodes))
    e = DecisionEngine(ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, startup_grace_s=0.0))
    e.adopt_or_start(reports(0.0), 0.0)
    return e


def test_a_node_paused_at_home_that_fails_out_there_comes_home_and_stays_for_t(engine):
    engine.tick(reports(1.0), 1.0)
    assert engine.mapping()["amcl"] == "laptop"
    engine.observe_handoff("amcl", pose_handoff_params(1.0, 2.0, 0.5, 0.1, 0.1, 0.05, 8.0))
    r = reports(10.0, laptop_running=("ar_recognition",))
    r["laptop"] = dataclasses.replace(r["laptop"], ended={"amcl": "signal 11"})
    result = engine.tick(r, 10.0)
    starts = [a for a in result.actions if isinstance(a, StartNode) and a.node == "amcl"]
    assert [(a.scale, a.lease_s) for a in starts] == [("robot", 0.0)]
    assert dict(starts[0].param_overrides)["initial_pose_x"] == 1.0
    [event] = [e for e in result.events if e.node == "amcl"]
    assert (event.kind, event.from_scale, event.to_scale) == ("migrate_back", "laptop", "robot")
    assert "ended on laptop: signal 11; its paused instance at home resumed" in event.reason
    assert engine.mapping()["amcl"] == "robot"
    # The allocator would move it out again at once; T holds it home (the paper's hysteresis).
    assert engine.tick(reports(15.0, laptop_running=("ar_recognition",)), 15.0).events == []
    assert engine.mapping()["amcl"] == "robot"
    moved = engine.tick(reports(20.5, laptop_running=("ar_recognition",)), 20.5)
    assert [(e.kind, e.node) for e in moved.events] == [("migrate", "amcl")]


def test_a_status_sampled_before_a_start_was_answered_is_no_crash_of_it_however_late(engine):
    # The main command on 2026-11-28: AMCL's laptop instance stopped (signal 9, the agent's
    # kill once it had left the master) during a 10 s link loss; AMCL moved out again when the
    # link came back, and a laptop status sampled during the loss, queued on the old
    # connection, arrived 0.14 s after that start was answered: it read as a crash of the new
    # instance and sent AMCL home again.
    engine.tick(reports(1.0), 1.0)
    assert engine.mapping()["amcl"] == "laptop"
    engine.start_acknowledged("amcl", 9.5)
    stale = reports(10.0, laptop_running=("ar_recognition",))
    stale["laptop"] = dataclasses.replace(stale["laptop"], ended={"amcl": "signal 9"},
                                          sampled_at=9.0)
    assert [e for e in engine.tick(stale, 10.0).events if e.node == "amcl"] == []
    assert engine.mapping()["amcl"] == "laptop"
    # Sampled after the answer, the same report is the new instance's end.
    fresh = reports(10.5, laptop_running=("ar_recognition",))
    fresh["laptop"] = dataclasses.replace(fresh["laptop"], ended={"amcl": "signal 9"},
                                          sampled_at=10.4)
    assert [(e.kind, e.node) for e in engine.tick(fresh, 10.5).events] == [("migrate_back",
                                                                           "amcl")]


def crashed_ekf_restarts(e, t, starting=frozenset(), moves_allowed=True):
    r = reports(t, laptop=False)
    r["robot"] = dataclasses.replace(r["robot"], ended={"ekf": "signal 6"})
    return [ev.node for ev in e.tick(r, t, moves_allowed=moves_allowed,
                                     starting=starting).events if ev.kind == "restart"]


def test_restarts_come_at_once_then_back_off(testbed_ch):
    backoff = BackoffParams(first_delay_s=1.0, max_delay_s=4.0, reset_after_s=30.0)
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, startup_grace_s=5.0, restart=backoff))
    e.adopt_or_start(reports(0.0, laptop=False), 0.0)
    assert crashed_ekf_restarts(e, 0.5, starting={"ekf"}) == []    # a start not answered yet
    assert crashed_ekf_restarts(e, 1.0) == ["ekf"]          # at once, within the start's grace
    e.start_acknowledged("ekf", 1.1)
    assert crashed_ekf_restarts(e, 1.05) == []              # received before the start's answer
    # It keeps failing: 1 s, 2 s, then 4 s (the limit) between restarts.
    times = [t / 10 for t in range(12, 200)]
    restarted_at = [t for t in times if crashed_ekf_restarts(e, t)]
    assert restarted_at[:4] == pytest.approx([2.0, 4.0, 8.0, 12.0])


def test_a_node_that_ran_long_enough_restarts_at_once_again():
    b = RestartBackoff(BackoffParams(first_delay_s=1.0, max_delay_s=8.0, reset_after_s=10.0))
    assert b.due(0.0)
    b.restarted(0.0)
    assert not b.due(0.5) and b.due(1.0)
    b.restarted(1.0)
    assert b.delay_s() == 2.0
    # It runs 10 s, then ends again: a new failure, not the same loop.
    assert b.due(11.0) and b.delay_s() == 0.0


def test_restarts_during_the_initial_configuration(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), PAPER)
    e.adopt_or_start(reports(0.0, laptop=False), 0.0)
    # A stock node that exits when its input does not exist yet (topic_tools transform).
    assert crashed_ekf_restarts(e, 1.0, moves_allowed=False) == ["ekf"]


def test_no_restart_on_a_scale_that_cannot_be_reached(engine):
    engine.tick(reports(1.0), 1.0)
    r = reports(9.0)
    r["laptop"] = dataclasses.replace(r["laptop"], received_at=0.0, ended={"amcl": "signal 9"})
    assert [ev for ev in engine.tick(r, 9.0).events if ev.kind == "restart"] == []
