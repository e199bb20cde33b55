"""`anyscale top`'s frame, rendered from constructed messages (no roscore)."""
import math

import pytest

pytest.importorskip("anyscale_msgs.msg")  # the built workspace's messages

import rospy  # noqa: E402
from anyscale_msgs.msg import (  # noqa: E402
    LinkStatistics, Mapping, MigrationEvent, NodeAssignment, NodeProcess, ScaleStatus,
    TopicStatistics)

from anyscale_core.top_view import render  # noqa: E402


def frame(testbed, **kw):
    robot = ScaleStatus(scale="robot", is_master=True, cores=2, cpu_percent=55.0,
                        memory_total_bytes=4 * 2**30, memory_available_bytes=3 * 2**30)
    robot.nodes = [NodeProcess(name="/amcl", state=NodeProcess.EXITED),
                   NodeProcess(name="/amcl", state=NodeProcess.STANDBY, rss_bytes=80 * 2**20),
                   NodeProcess(name="/laser", state=NodeProcess.RUNNING, cpu_percent=3.0,
                               rss_bytes=20 * 2**20)]
    robot.topics = [TopicStatistics(topic="/scan", rate_hz=9.8, last_message_age_s=0.1),
                    TopicStatistics(topic="/amcl_pose", rate_hz=1.0, last_message_age_s=0.2)]
    laptop = ScaleStatus(scale="laptop", cores=4, cpu_percent=20.0,
                         link=LinkStatistics(peer_scale="robot", up=True, rtt_mean_s=0.004,
                                             bandwidth_mbps=18.0))
    laptop.nodes = [NodeProcess(name="/amcl", state=NodeProcess.RUNNING, cpu_percent=36.0,
                                rss_bytes=150 * 2**20, lease_expiry=rospy.Time(102, 500000000))]
    laptop.topics = [TopicStatistics(topic="/scan", rate_hz=10.0, last_message_age_s=0.05)]
    mapping = Mapping(perf=180.0, objective=5000.0, allocator="paper")
    mapping.assignments = [NodeAssignment(node=n.name, scale="robot") for n in testbed.nodes]
    mapping.assignments[[n.name for n in testbed.nodes].index("amcl")].scale = "laptop"
    events = [MigrationEvent(kind=MigrationEvent.MIGRATE, node="amcl", from_scale="robot",
                             to_scale="laptop", reason="laptop can take it", duration_s=0.8,
                             success=True)]
    args = dict(statuses={"robot": robot, "laptop": laptop}, mapping=mapping, events=events,
                model=testbed, now=100.0)
    args.update(kw)
    return render(**args)


def row(text, first):
    return next(ln for ln in text.splitlines() if ln.split()[:1] == [first])


def test_scales_nodes_connections_and_events(testbed):
    text = frame(testbed)
    assert "Perf (Eq. 1) 180.0" in text
    assert row(text, "robot").split()[1:4] == ["55.0%", "25.0%", "master"]
    assert "up" in row(text, "laptop") and "4.0 ms" in row(text, "laptop")
    assert "18.0 Mbit/s" in row(text, "laptop")
    amcl = row(text, "amcl").split()              # the live instance, not the exited one
    assert amcl[:4] == ["amcl", "laptop", "RUNNING", "36.0%"] and "2.5" in amcl
    assert row(text, "laser").split()[:3] == ["laser", "robot", "RUNNING"]
    assert "warm standby: amcl on robot (80 MB)" in text   # not a row: it is no node yet
    assert "not seen" in row(text, "ekf")
    scan_amcl = row(text, "laser->amcl")          # measured where amcl runs: the laptop
    assert "10.0 Hz" in scan_amcl and scan_amcl.endswith("ok")
    assert "below min" in row(text, "amcl->ekf")  # 1 Hz on the robot
    assert "MIGRATE" in text and "laptop can take it" in text and "0.80 s" in text
    assert "uplink" not in text                   # the robot watches none here


def test_the_masters_uplink_carrier(testbed):
    statuses = {"robot": ScaleStatus(scale="robot", is_master=True, link=LinkStatistics(
        up=False, uplink_interface="wlan0", carrier=False))}
    text = frame(testbed, statuses=statuses)
    assert "uplink of robot: wlan0, NO CARRIER" in text
    statuses["robot"].link.carrier = statuses["robot"].link.up = True
    assert "uplink of robot: wlan0, carrier" in frame(testbed, statuses=statuses)


def test_without_mapping_model_or_events(testbed):
    text = frame(testbed, mapping=None, model=None, events=[])
    assert "none yet" in text and "CONNECTION" not in text
    assert row(text, "amcl").split()[1] == "laptop"
    assert "none" in text.splitlines()[-1]


def test_a_link_down_and_unknown_values_show_plainly(testbed):
    status = ScaleStatus(scale="laptop", link=LinkStatistics(up=False, rtt_mean_s=math.nan,
                                                             bandwidth_mbps=math.nan))
    text = frame(testbed, statuses={"laptop": status})
    assert row(text, "laptop").split()[3:6] == ["DOWN", "-", "-"]
    assert "not measured on robot" in row(text, "odometry->ekf")


def test_top_without_a_master_says_so(monkeypatch, capsys):
    from anyscale_core.cli import main
    monkeypatch.setenv("ROS_MASTER_URI", "http://127.0.0.1:9/")   # nothing listens there
    assert main(["top", "--once"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("anyscale top: error: no ROS master at http://127.0.0.1:9/")


def test_a_paused_instance_is_listed_apart_and_never_hides_the_running_one(testbed):
    robot = ScaleStatus(scale="robot", is_master=True, cores=2)
    robot.nodes = [NodeProcess(name="/amcl", state=NodeProcess.PAUSED, rss_bytes=90 * 2**20)]
    laptop = ScaleStatus(scale="laptop", cores=4)
    laptop.nodes = [NodeProcess(name="/amcl", state=NodeProcess.RUNNING, cpu_percent=30.0)]
    # Scales in both orders: the paused row must not replace the running one either way.
    for statuses in ({"robot": robot, "laptop": laptop}, {"zz_robot": robot, "laptop": laptop}):
        text = frame(testbed, statuses=statuses)
        assert row(text, "amcl").split()[2] == "RUNNING"
        assert "paused (resumed by a return): amcl on" in text and "(90 MB)" in text


def test_the_live_cost_estimates_beside_the_models_figures(testbed):
    from anyscale_msgs.msg import CostEstimate, CostEstimates
    costs = CostEstimates(estimates=[
        CostEstimate(node="amcl", scale="laptop", model_percent=36.0, live_percent=152.4,
                     measured_percent=152.4, samples=40, lower_bound=True, retry_in_s=8.6,
                     failures=2, reason="laptop CPU 60 % + 80 % estimated for it"),
        CostEstimate(node="amcl", scale="robot", model_percent=50.0, live_percent=50.0,
                     measured_percent=math.nan, samples=0)])
    text = frame(testbed, costs=costs)
    lines = text.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.startswith("CPU COST"))
    assert lines[head + 1].split() == ["amcl", "on", "laptop", "36", "152.4", "≥152.4", "40", "2",
                                       "failed", "in", "a", "row,", "9", "s", "left:", "laptop",
                                       "CPU", "60", "%", "+", "80", "%", "estimated", "for",
                                       "it"]
    assert lines[head + 2].split() == ["amcl", "on", "robot", "50", "50.0", "-", "0", "-"]
    assert "CPU COST" not in frame(testbed)       # no decision node publishing them yet


def test_the_link_ahead_of_each_remote_scale_from_the_decision_nodes_diagnostics(testbed):
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    status = DiagnosticStatus(name="anyscale_decision: link ahead", hardware_id="anyscale_decision",
                              message="amcl home: link ahead: 0.0 Mbit/s in 2.8 s")
    status.values = [KeyValue("laptop", "24 Mbit/s for 12 s, then 0 Mbit/s (lost 100 %) from "
                                        "12 s (at 0.40 m/s)")]
    text = frame(testbed, link_ahead=status)
    assert ("link ahead (laptop): 24 Mbit/s for 12 s, then 0 Mbit/s (lost 100 %) from 12 s "
            "(at 0.40 m/s)") in text.splitlines()
    assert "link ahead: amcl home: link ahead: 0.0 Mbit/s in 2.8 s" in text.splitlines()
    assert "link ahead" not in frame(testbed)
