"""A status with a non-finite or out-of-range figure is refused, naming the field, and the
decision engine's smoothed load keeps its last good value; a sound status passes."""
import math

import pytest

pytest.importorskip("anyscale_msgs.msg")  # the built workspace's messages

from anyscale_msgs.msg import (LinkStatistics, NodeProcess, ScaleStatus,  # noqa: E402
                               TopicStatistics)

from anyscale_core.status_check import status_problem  # noqa: E402

from decision_reports import reports  # noqa: E402


def sound():
    msg = ScaleStatus(scale="laptop", cores=4, cpu_quota_cores=0.9, cpu_percent=25.0,
                      cpu_max_ghz=2.4, sample_period_s=0.5,
                      link=LinkStatistics(up=True, rtt_s=math.nan, rtt_mean_s=0.002,
                                          loss_ratio=0.0, bandwidth_mbps=math.nan))
    msg.nodes = [NodeProcess(name="/amcl", state=NodeProcess.RUNNING, cpu_percent=390.0)]
    msg.topics = [TopicStatistics(topic="/scan", rate_hz=10.0, last_message_age_s=math.inf,
                                  bytes_per_second=1e5, window_s=2.0)]
    return msg


def test_a_sound_status_passes():
    assert status_problem(sound()) is None


BAD = [
    (lambda m: setattr(m, "cpu_percent", math.nan), "cpu_percent"),
    (lambda m: setattr(m, "cpu_percent", 250.0), "cpu_percent"),
    (lambda m: setattr(m, "cpu_percent", -1.0), "cpu_percent"),
    (lambda m: setattr(m, "cpu_held_percent", math.nan), "cpu_held_percent"),
    (lambda m: setattr(m, "cpu_held_percent", 101.0), "cpu_held_percent"),
    (lambda m: setattr(m, "cpu_quota_cores", math.inf), "cpu_quota_cores"),
    (lambda m: setattr(m, "cores", 0), "cores"),
    (lambda m: setattr(m, "sample_period_s", math.nan), "sample_period_s"),
    (lambda m: setattr(m.nodes[0], "cpu_percent", math.nan), "nodes[0] (/amcl).cpu_percent"),
    (lambda m: setattr(m.nodes[0], "cpu_percent", 1e9), "nodes[0] (/amcl).cpu_percent"),
    (lambda m: setattr(m.topics[0], "rate_hz", math.inf), "topics[0] (/scan).rate_hz"),
    (lambda m: setattr(m.topics[0], "rate_hz", -5.0), "topics[0] (/scan).rate_hz"),
    (lambda m: setattr(m.topics[0], "last_message_age_s", math.nan),
     "topics[0] (/scan).last_message_age_s"),
    (lambda m: setattr(m.link, "bandwidth_mbps", math.inf), "link.bandwidth_mbps"),
    (lambda m: setattr(m.link, "bandwidth_mbps", -3.0), "link.bandwidth_mbps"),
    (lambda m: setattr(m.link, "loss_ratio", 2.0), "link.loss_ratio"),
]


@pytest.mark.parametrize("spoil,field", BAD, ids=[b[1] for b in BAD])
def test_a_bad_figure_is_refused_naming_the_field(spoil, field):
    msg = sound()
    spoil(msg)
    problem = status_problem(msg)
    assert problem is not None and problem.startswith(field + " "), problem


def test_a_nan_load_does_not_freeze_the_smoothed_load(engine):
    # One ScaleStatus with cpu_percent NaN kept the laptop's smoothed load at NaN (np.clip and
    # the smoothing both keep NaN): every CPU check failed until the decision node restarted.
    good = engine.tick(reports(1.0, laptop_load=30.0), 1.0).state.scale_load["laptop"]
    assert math.isfinite(good)
    state = engine.tick(reports(2.0, laptop_load=math.nan), 2.0).state
    assert state.scale_load["laptop"] == good
    state = engine.tick(reports(30.0, laptop_load=10.0), 30.0).state
    assert state.scale_load["laptop"] == pytest.approx(10.0, abs=0.1)


def test_the_refusal_names_what_was_wrong():
    msg = sound()
    msg.cpu_percent = math.nan
    assert status_problem(msg) == "cpu_percent is nan (expected a number from 0 to 100)"
