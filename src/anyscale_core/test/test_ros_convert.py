"""The decision node's message conversions and parameter checks, on constructed messages
(no roscore)."""
import math

import pytest

pytest.importorskip("anyscale_msgs.msg")  # the built workspace's messages

from anyscale_msgs.msg import (LinkStatistics, MigrationEvent, NodeProcess,  # noqa: E402
                               ScaleStatus, TopicStatistics)
from geometry_msgs.msg import PoseWithCovarianceStamped  # noqa: E402

from anyscale_core import ros_convert as conv  # noqa: E402
from anyscale_core.decision_params import ParamError, read_params  # noqa: E402


def status(scale="laptop", is_master=False, **kw):
    msg = ScaleStatus(scale=scale, is_master=is_master, cores=4, cpu_percent=25.0,
                      link=LinkStatistics(peer_scale="robot", up=True, bandwidth_mbps=12.5))
    msg.nodes = [NodeProcess(name="/amcl", state=NodeProcess.RUNNING, cpu_percent=40.0),
                 NodeProcess(name="/ar_recognition", state=NodeProcess.STARTING, cpu_percent=5.0),
                 NodeProcess(name="/old", state=NodeProcess.EXITED, cpu_percent=0.0),
                 NodeProcess(name="/amcl_gone", state=NodeProcess.LEASE_EXPIRED),
                 NodeProcess(name="/rviz", state=NodeProcess.RUNNING, cpu_percent=9.0),
                 NodeProcess(name="/old", state=NodeProcess.STANDBY, cpu_percent=60.0)]
    msg.topics = [TopicStatistics(topic="/scan", rate_hz=10.0, last_message_age_s=0.05),
                  TopicStatistics(topic="/amcl_pose", rate_hz=5.0, last_message_age_s=2.0),
                  TopicStatistics(topic="/never", rate_hz=0.0, last_message_age_s=math.inf)]
    for k, v in kw.items():
        setattr(msg, k, v)
    return msg


def test_scale_report_keeps_live_model_nodes_and_effective_rates():
    names = ["amcl", "ar_recognition", "old", "amcl_gone"]
    r = conv.scale_report_from_msg(status(), 12.0, names)
    assert (r.scale, r.received_at, r.cpu_percent, r.capacity_cores) == ("laptop", 12.0, 25.0, 4.0)
    assert r.running == {"amcl": 40.0, "ar_recognition": 5.0}   # rviz is not in the model
    assert r.standby_cpu == 60.0                                 # a standby is not running
    assert r.topic_rates["/scan"] == 10.0
    assert r.topic_rates["/amcl_pose"] == pytest.approx(0.5)     # silent for 2 s
    assert r.topic_rates["/never"] == 0.0
    assert r.topic_silence == {"/scan": pytest.approx(0.05), "/amcl_pose": 2.0, "/never": math.inf}
    assert r.link_up and r.bandwidth_mbps == 12.5
    assert r.cpu_held == 0.0                                     # a scale of its own
    assert conv.scale_report_from_msg(status(cpu_held_percent=60.0), 12.0, names).cpu_held == 60.0


def test_a_report_is_dated_by_its_stamp_not_by_its_arrival():
    assert conv.scale_report_from_msg(status(), 12.0, [], 3.5).sample_time() == 8.5
    assert conv.scale_report_from_msg(status(), 12.0, [], -0.2).sample_time() == 12.0  # clock ahead
    assert conv.scale_report_from_msg(status(), 12.0, []).sample_time() == 12.0
    assert conv.scale_report_from_msg(status(), 12.0, [], math.nan).sample_time() == 12.0


def test_scale_report_uses_the_quota_and_the_masters_link_is_its_uplink_carrier():
    msg = status("robot", True, cpu_quota_cores=1.5)
    msg.link = LinkStatistics(up=True, bandwidth_mbps=float("nan"), carrier=True)
    r = conv.scale_report_from_msg(msg, 0.0, [])
    assert r.capacity_cores == 1.5 and r.link_up and math.isnan(r.bandwidth_mbps)
    msg.link = LinkStatistics(up=False, bandwidth_mbps=12.0, uplink_interface="wlan0",
                              carrier=False)
    r = conv.scale_report_from_msg(msg, 0.0, [])
    assert not r.link_up and math.isnan(r.bandwidth_mbps)
    down = conv.scale_report_from_msg(status(link=LinkStatistics(up=False)), 0.0, [])
    assert not down.link_up


def test_watched_topics_follow_the_subscribers_scale(testbed):
    mapping = {n.name: "robot" for n in testbed.nodes}
    mapping["amcl"] = "laptop"
    lists = conv.watched_topics(testbed, mapping)
    into_amcl = sorted({(c.topic, "/amcl") for c in testbed.connections if c.subscriber == "amcl"})
    assert lists["laptop"] == into_amcl
    assert {t for t, _ in lists["robot"]} == {c.topic for c in testbed.connections
                                              if c.subscriber != "amcl"}
    assert ("/amcl_pose", "/ekf") in lists["robot"]  # amcl publishes it, the robot's EKF receives
    # A topic with two subscribers on one scale is listed for each: counted while either runs.
    scan_readers = {n for t, n in lists["robot"] if t == "/scan"}
    assert scan_readers == {"/" + c.subscriber for c in testbed.connections
                            if c.topic == "/scan" and c.subscriber != "amcl"}


@pytest.mark.parametrize("value, text", [(1.5, "1.5"), (float("nan"), ".nan"),
                                         (float("-inf"), "-.inf"), (True, "true"), (3, "3")])
def test_param_overrides_are_yaml_text(value, text):
    kv = conv.param_overrides_to_kv([("initial_pose_x", value)])
    assert (kv[0].key, kv[0].value) == ("initial_pose_x", text)


def test_pose_handoff_reads_position_yaw_and_covariance():
    msg = PoseWithCovarianceStamped()
    msg.pose.pose.position.x, msg.pose.pose.position.y = 1.0, -2.0
    msg.pose.pose.orientation.z = math.sin(0.75)       # yaw 1.5 rad
    msg.pose.pose.orientation.w = math.cos(0.75)
    cov = [0.0] * 36
    cov[0], cov[7], cov[35] = 0.25, 0.5, 0.1
    msg.pose.covariance = cov
    p = conv.handoff_params_from_pose(msg)
    assert p["initial_pose_x"] == 1.0 and p["initial_pose_y"] == -2.0
    assert p["initial_pose_a"] == pytest.approx(1.5)
    assert (p["initial_cov_xx"], p["initial_cov_yy"], p["initial_cov_aa"]) == (0.25, 0.5, 0.1)


def test_mapping_and_event_messages():
    m = conv.mapping_msg({"amcl": "laptop", "laser": "robot"}, 12.5, 100.0, "paper", None)
    assert [(a.node, a.scale) for a in m.assignments] == [("amcl", "laptop"), ("laser", "robot")]
    assert (m.perf, m.objective, m.allocator) == (12.5, 100.0, "paper")
    e = conv.event_msg("migrate_back", "amcl", "laptop", "robot", "link to laptop down", None,
                       0.4)
    assert (e.kind, e.success, e.duration_s) == (MigrationEvent.MIGRATE_BACK, True, 0.4)
    failed = conv.event_msg("failed", "amcl", "robot", "laptop", "refused", None, success=False)
    assert failed.kind == MigrationEvent.FAILED and math.isnan(failed.duration_s)


def test_describe_change_names_every_move_and_reason():
    line = conv.describe_change({"a": "robot", "b": "robot"}, {"a": "laptop", "b": "robot"},
                                {"a": "laptop can take it"})
    assert line == "mapping changed: a robot -> laptop (laptop can take it)"


def params(**given):
    return lambda name, default=None: given.get(name.lstrip("~"), default)


def test_params_defaults_and_errors():
    p = read_params(params(model="/m.yaml"))
    assert (p.model, p.allocator, p.period_s) == ("/m.yaml", "paper", 1.0)
    assert (p.engine.hysteresis_s, p.engine.lease_s, p.engine.status_timeout_s) == (10.0, 3.0, 1.5)
    assert (p.engine.act_at_tolerance, p.engine.startup_grace_s) == (0.5, 5.0)
    assert p.stop_sigint_timeout_s == 0.5
    with pytest.raises(ParamError, match="~model"):
        read_params(params())
    with pytest.raises(ParamError, match="~period_s"):
        read_params(params(model="/m.yaml", period_s="fast"))
    with pytest.raises(ParamError, match="~lease_s"):
        read_params(params(model="/m.yaml", lease_s=-1))
    with pytest.raises(ParamError, match="~act_at_tolerance"):
        read_params(params(model="/m.yaml", act_at_tolerance=1.5))
    assert (p.engine.bandwidth_margin, p.engine.bandwidth_stay_margin) == (0.3, 0.15)
    assert p.engine.weak_link_mbps == 0.0
    with pytest.raises(ParamError, match="~bandwidth_stay_margin .0.4. must not exceed"):
        read_params(params(model="/m.yaml", bandwidth_stay_margin=0.4))
    assert p.control_nice == 0
    assert read_params(params(model="/m.yaml", control_nice=-5)).control_nice == -5
    for bad in (3, -21, 1.5, "high", True):
        with pytest.raises(ParamError, match="~control_nice: expected an integer >= -20 and <= 0"):
            read_params(params(model="/m.yaml", control_nice=bad))


def test_scale_report_names_the_nodes_that_ended_and_how():
    msg = status()
    msg.nodes += [NodeProcess(name="/ekf", state=NodeProcess.EXITED, exit_code=-1, exit_signal=11),
                  NodeProcess(name="/navigation", state=NodeProcess.EXITED, exit_code=1,
                              log_file="/logs/navigation.log"),
                  NodeProcess(name="/user", state=NodeProcess.EXITED, exit_code=0),
                  NodeProcess(name="/amcl", state=NodeProcess.EXITED, exit_code=1)]
    r = conv.scale_report_from_msg(msg, 0.0, ["amcl", "ekf", "navigation", "user", "amcl_gone"])
    # /amcl has a live instance; /amcl_gone's lease expired: ended too, which matters where the
    # node is due to run (the engine looks at that scale's report only).
    assert r.ended == {"ekf": "signal 11", "navigation": "exit code 1, log /logs/navigation.log",
                       "user": "exit code 0", "amcl_gone": "its lease ran out (exit code 0)"}


def test_cost_estimates_message_and_when_it_is_sent_again():
    from anyscale_core.cost_estimate import CostRow
    from anyscale_core.placement_learning import PlacementRow
    rows = [PlacementRow(CostRow("amcl", "laptop", 36.0, 80.2, 80.2, 12, True, 0.9), 9.4, 1,
                         "laptop CPU 60 % + 80 % estimated for it"),
            PlacementRow(CostRow("amcl", "robot", 50.0, 50.0, math.nan, 0, False, math.nan),
                         0.0, 0, "")]
    msg = conv.cost_estimates_msg(rows, 0)
    [out, home] = msg.estimates
    assert (out.node, out.scale, out.model_percent, out.live_percent, out.samples,
            out.lower_bound, out.retry_in_s, out.failures) == \
        ("amcl", "laptop", 36.0, 80.2, 12, True, 9.4, 1)
    assert out.reason.startswith("laptop CPU") and math.isnan(home.measured_percent)
    key = conv.cost_estimates_key(rows)
    assert conv.cost_estimates_key([PlacementRow(rows[0].cost, 9.1, 1, rows[0].reason),
                                    rows[1]]) == key          # the same to the second shown
    assert conv.cost_estimates_key([PlacementRow(rows[0].cost, 8.9, 1, rows[0].reason),
                                    rows[1]]) != key
