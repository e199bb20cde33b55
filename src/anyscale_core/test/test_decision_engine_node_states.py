"""A node due to run on a scale where the agent reports it anything but running: ended by its
lease (LEASE_EXPIRED), paused (a pause nobody undid), or not listed at all (the agent's
successor after a graceful shutdown) is started there again; agent statuses go through
ros_convert as the decision node's wrapper converts them."""
import dataclasses

import pytest

pytest.importorskip("anyscale_msgs.msg")  # the built workspace's messages

from anyscale_msgs.msg import NodeProcess, ScaleStatus  # noqa: E402

from anyscale_core import ros_convert as conv  # noqa: E402
from anyscale_core.decision_types import StartNode  # noqa: E402

from decision_reports import reports  # noqa: E402


def robot_status(processes):
    """The robot agent's status listing `processes` (node -> state), as a ScaleReport."""
    msg = ScaleStatus(scale="robot", is_master=True, cores=2, cpu_percent=40.0)
    msg.nodes = [NodeProcess(name="/" + n, state=s, pid=0 if s != NodeProcess.RUNNING else 9)
                 for n, s in processes.items()]
    return msg


def robot_report(engine, now, processes):
    report = conv.scale_report_from_msg(robot_status(processes), now, engine.ch.node_names)
    out = reports(now)
    out["robot"] = dataclasses.replace(out["robot"], **{
        k: getattr(report, k) for k in ("running", "ended", "paused", "listed")})
    return out


def all_running(engine, **states):
    processes = {n: NodeProcess.RUNNING for n in engine.ch.node_names}
    processes.update(states)
    return processes


def starts(result, node):
    return [(a.node, a.scale, a.lease_s) for a in result.actions
            if isinstance(a, StartNode) and a.node == node]


def test_a_lease_expired_where_the_node_is_due_to_run_counts_as_ended(engine):
    # A forged start_node{lease_s: 1e-6} on the robot got a driver SIGKILLed as LEASE_EXPIRED,
    # and the decision node, which counted only EXITED as ended, never started it again.
    report = conv.scale_report_from_msg(
        robot_status({"laser": NodeProcess.LEASE_EXPIRED}), 5.0, engine.ch.node_names)
    assert "laser" in report.ended
    result = engine.tick(robot_report(engine, 5.0, all_running(
        engine, laser=NodeProcess.LEASE_EXPIRED)), 5.0, moves_allowed=False)
    assert starts(result, "laser") == [("laser", "robot", 0.0)]


def test_a_node_found_paused_where_it_is_due_to_run_is_resumed_within_one_period(engine):
    # stop_node{pause: true} on a laser driver left it SIGSTOPped: neither running nor ended.
    result = engine.tick(robot_report(engine, 5.0, all_running(
        engine, laser=NodeProcess.PAUSED)), 5.0, moves_allowed=False)
    assert starts(result, "laser") == [("laser", "robot", 0.0)]
    [event] = [e for e in result.events if e.node == "laser"]
    assert "paused on robot" in event.reason
    # Not while its start is under way, nor on a report sampled before the start's answer.
    assert starts(engine.tick(robot_report(engine, 5.5, all_running(
        engine, laser=NodeProcess.PAUSED)), 5.5, starting={"laser"}), "laser") == []
    engine.start_acknowledged("laser", 6.0)
    stale = robot_report(engine, 6.5, all_running(engine, laser=NodeProcess.PAUSED))
    stale["robot"] = dataclasses.replace(stale["robot"], sampled_at=5.9)
    assert starts(engine.tick(stale, 6.5), "laser") == []


def test_a_paused_instance_at_home_of_a_node_that_runs_out_there_is_left_alone(engine):
    engine.tick(reports(1.0), 1.0)                      # amcl to the laptop (paused at home)
    assert engine.mapping()["amcl"] == "laptop"
    r = robot_report(engine, 5.0, all_running(engine, amcl=NodeProcess.PAUSED))
    r["laptop"] = dataclasses.replace(r["laptop"], running={"amcl": 10.0})
    assert starts(engine.tick(r, 5.0), "amcl") == []


def test_a_node_the_agent_does_not_list_where_it_is_due_to_run_is_started(engine):
    # A graceful shutdown of the robot's agent (SIGTERM, or XML-RPC shutdown by anyone on the
    # graph) stops every node it runs, and its successor lists none of them.
    processes = all_running(engine)
    del processes["laser"], processes["odometer"]
    result = engine.tick(robot_report(engine, 5.0, processes), 5.0, moves_allowed=False)
    assert starts(result, "laser") == [("laser", "robot", 0.0)]
    assert starts(result, "odometer") == [("odometer", "robot", 0.0)]
    [event] = [e for e in result.events if e.node == "laser"]
    assert "not listed by the agent of robot" in event.reason


def test_a_standby_is_no_instance_and_a_stopping_one_is_not_missing(engine):
    report = conv.scale_report_from_msg(
        robot_status({"amcl": NodeProcess.STANDBY, "ekf": NodeProcess.STOPPING}), 5.0,
        engine.ch.node_names)
    assert "amcl" not in report.listed and "ekf" in report.listed
    assert "ekf" not in report.ended and "ekf" not in report.running
