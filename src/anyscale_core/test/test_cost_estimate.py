"""The live cost estimate: seeded from the model, learned from the agents' reports while a node
runs on a scale, a saturated scale's share scaled by the rates the node fell short of, single
odd samples outvoted, and what is not refreshed relaxing toward the model's figure."""
from dataclasses import replace
import math

import numpy as np
import pytest

from anyscale_core.cost_estimate import (MEDIAN_OF, SATURATED_PERCENT, CostEstimates,
                                         CostFilter)
from anyscale_core.decision_types import ScaleReport

from decision_reports import HEALTHY

LAPTOP_CORES = 0.9


def amcl_out(ch):
    """Every node on the robot but AMCL, on the laptop."""
    assign = ch.initial_mapping()
    assign[ch.node_index("amcl")] = ch.scale_index("laptop")
    return assign


def laptop_reports(t, amcl_core_percent, busy, scan_hz=10.0, pose_hz=5.0, robot_busy=50.0):
    """Both scales' reports at t: AMCL taking `amcl_core_percent` of one core on the 0.9-core
    laptop, which is `busy` % busy, with /scan there and /amcl_pose on the robot at the given
    rates."""
    rates = {**HEALTHY, "/scan": scan_hz, "/amcl_pose": pose_hz}
    return {"robot": ScaleReport("robot", t, robot_busy, 0.34, {"laser": 2.0}, rates),
            "laptop": ScaleReport("laptop", t, busy, LAPTOP_CORES, {"amcl": amcl_core_percent},
                                  rates, True, 20.0)}


def learn(est, assign, samples, start=0.0, period=0.2, settled=lambda i: True):
    """Feeds `samples` (a list of keyword dicts for laptop_reports) one per period."""
    t = start
    for kw in samples:
        est.observe(laptop_reports(t, **kw), assign, t, 2.0, settled)
        t += period
    return t - period


def test_seeded_from_the_model(testbed_ch):
    est = CostEstimates(testbed_ch, 5.0, 300.0)
    np.testing.assert_array_equal(est.matrix(100.0), testbed_ch.cpu)
    rows = {(r.node, r.scale): r for r in est.rows(0.0)}
    assert rows["amcl", "laptop"].live == rows["amcl", "laptop"].model == 36
    assert math.isnan(rows["amcl", "laptop"].measured) and rows["amcl", "laptop"].samples == 0
    # Only where a node may run: the critical nodes' laptop figures are not estimates.
    assert ("odometry", "laptop") not in rows and ("odometry", "robot") in rows


def test_updated_while_the_node_runs_there(testbed_ch):
    est = CostEstimates(testbed_ch, 5.0, 300.0)
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    # 18 % of one core on 0.9 cores: 20 % of the laptop, the laptop with room (40 % busy).
    t = learn(est, amcl_out(testbed_ch), [dict(amcl_core_percent=18.0, busy=40.0)] * 150)
    assert est.live(amcl, laptop, t) == pytest.approx(20.0, abs=0.1)
    row = next(r for r in est.rows(t) if (r.node, r.scale) == ("amcl", "laptop"))
    assert row.samples == 150 and not row.lower_bound and row.capacity_cores == LAPTOP_CORES
    assert est.matrix(t)[amcl, laptop] == pytest.approx(20.0, abs=0.1)
    # The master's figures plan as the model has them (it is exempt from the CPU limit).
    assert est.matrix(t)[amcl, testbed_ch.master] == testbed_ch.cpu[amcl, testbed_ch.master]


def test_the_average_follows_report_time_not_the_number_of_reports(testbed_ch):
    """One time constant of samples moves it 63 % of the way, at 5 Hz as at 1 Hz."""
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    moved = []
    for period in (0.2, 1.0):
        est = CostEstimates(testbed_ch, 5.0, 300.0)
        n = round(5.0 / period) + MEDIAN_OF // 2   # the first samples only fill the median
        t = learn(est, amcl_out(testbed_ch), [dict(amcl_core_percent=9.0, busy=30.0)] * n,
                  period=period)
        moved.append((36.0 - est.live(amcl, laptop, t)) / (36.0 - 10.0))
    assert moved == pytest.approx([1 - math.exp(-1)] * 2, abs=0.01)


def test_a_saturated_scale_gives_a_lower_bound_scaled_by_the_rates_missed(testbed_ch):
    est = CostEstimates(testbed_ch, 5.0, 300.0)
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    # AMCL got 40 % of the saturated laptop and published /amcl_pose at 2.5 of its 5 Hz (on the
    # robot, where the EKF subscribes): it needs at least 80 %. Learned at once, not averaged:
    # it is a minimum.
    starved = dict(amcl_core_percent=36.0, busy=100.0, scan_hz=3.5, pose_hz=2.5)
    t = learn(est, amcl_out(testbed_ch), [starved] * 3)
    assert est.live(amcl, laptop, t) == pytest.approx(80.0)
    row = next(r for r in est.rows(t) if (r.node, r.scale) == ("amcl", "laptop"))
    assert row.lower_bound and row.measured == pytest.approx(80.0)
    # A share that says less never lowers it.
    t = learn(est, amcl_out(testbed_ch), [dict(starved, amcl_core_percent=18.0)] * 10,
              start=t + 0.2)
    assert est.live(amcl, laptop, t) == pytest.approx(80.0)


def test_the_outputs_say_what_the_node_got_done_not_its_inputs(testbed_ch):
    """/scan arrives at the laptop's agent at its full 10 Hz while AMCL, starved, publishes 2.5
    of its 5 poses a second: it needs twice its share. A node without a measured output is
    judged by its inputs."""
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    est = CostEstimates(testbed_ch, 5.0, 300.0)
    t = learn(est, amcl_out(testbed_ch), [dict(amcl_core_percent=36.0, busy=100.0,
                                               scan_hz=10.0, pose_hz=2.5)] * 3)
    assert est.live(amcl, laptop, t) == pytest.approx(80.0)
    est = CostEstimates(testbed_ch, 5.0, 300.0)
    no_pose = [laptop_reports(n * 0.2, 36.0, 100.0, scan_hz=4.0) for n in range(3)]
    for n, r in enumerate(no_pose):
        r["robot"] = replace(r["robot"], topic_rates={})
        est.observe(r, amcl_out(testbed_ch), n * 0.2, 2.0, lambda i: True)
    assert est.live(amcl, laptop, 0.4) == pytest.approx(100.0)     # 40 % at 4 of 10 Hz


def test_a_saturated_scale_where_the_node_meets_its_rates_is_a_measurement(testbed_ch):
    est = CostEstimates(testbed_ch, 0.0, 300.0)
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    t = learn(est, amcl_out(testbed_ch), [dict(amcl_core_percent=18.0, busy=SATURATED_PERCENT,
                                               scan_hz=9.5, pose_hz=4.6)] * 3)
    assert est.live(amcl, laptop, t) == pytest.approx(20.0)
    assert not next(r for r in est.rows(t) if r.node == "amcl" and r.scale == "laptop") \
        .lower_bound


def test_the_master_is_measured_as_it_comes_even_saturated(testbed_ch):
    """The model's master figures are the node's CPU at the rate the master sustains."""
    est = CostEstimates(testbed_ch, 0.0, 300.0)
    amcl = testbed_ch.node_index("amcl")
    home = testbed_ch.initial_mapping()
    for n in range(3):
        r = laptop_reports(n * 0.2, 0.0, 10.0, scan_hz=10.0, pose_hz=2.0, robot_busy=100.0)
        r["robot"] = replace(r["robot"], running={"amcl": 6.8})     # 20 % of 0.34 cores
        est.observe(r, home, n * 0.2, 2.0, lambda i: True)
    assert est.live(amcl, testbed_ch.master, 0.4) == pytest.approx(20.0)


@pytest.mark.parametrize("outlier", [100.0, 0.0])
def test_one_odd_sample_is_outvoted(testbed_ch, outlier):
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    steady = dict(amcl_core_percent=18.0, busy=40.0)
    # A burst (a callback's backlog, a sample across a stop) in one report, and its opposite,
    # against the same reports without it.
    odd = dict(steady, amcl_core_percent=outlier * LAPTOP_CORES)
    learnt = []
    for one in (odd, steady):
        est = CostEstimates(testbed_ch, 5.0, 300.0)
        t = learn(est, amcl_out(testbed_ch), [steady] * 20 + [one] + [steady] * 4)
        learnt.append(est.live(amcl, laptop, t))
    assert learnt[0] == pytest.approx(learnt[1], abs=1e-9)


def test_a_stays_first_samples_teach_nothing_until_the_median_holds(testbed_ch):
    est = CostEstimates(testbed_ch, 0.0, 300.0)
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    t = learn(est, amcl_out(testbed_ch), [dict(amcl_core_percent=90.0, busy=100.0,
                                               scan_hz=2.0, pose_hz=1.0)] * (MEDIAN_OF // 2))
    assert est.live(amcl, laptop, t) == 36.0


def test_not_refreshed_it_relaxes_toward_the_model(testbed_ch):
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    starved = dict(amcl_core_percent=36.0, busy=100.0, scan_hz=3.5, pose_hz=2.5)
    est = CostEstimates(testbed_ch, 5.0, 300.0)
    t = learn(est, amcl_out(testbed_ch), [starved] * 5)
    assert est.live(amcl, laptop, t + 300.0) == pytest.approx(36.0 + 44.0 / math.e)
    assert est.live(amcl, laptop, t + 3000.0) == pytest.approx(36.0, abs=0.01)
    row = next(r for r in est.rows(t + 300.0) if (r.node, r.scale) == ("amcl", "laptop"))
    assert row.measured == pytest.approx(80.0)       # what was learned, for writing back
    # Back there later, it learns on from what it believes then, not from the old figure.
    t2 = t + 300.0
    learn(est, amcl_out(testbed_ch), [dict(amcl_core_percent=18.0, busy=40.0)] * 3,
          start=t2, period=0.001)
    assert est.live(amcl, laptop, t2 + 0.002) == pytest.approx(36.0 + 44.0 / math.e, abs=0.1)
    never = CostEstimates(testbed_ch, 5.0, 0.0)
    t = learn(never, amcl_out(testbed_ch), [starved] * 5)
    assert never.live(amcl, laptop, t + 1e6) == pytest.approx(80.0)


def test_nothing_is_learned_from_a_start_a_stale_report_or_a_node_not_running(testbed_ch):
    amcl, laptop = testbed_ch.node_index("amcl"), testbed_ch.scale_index("laptop")
    starved = dict(amcl_core_percent=36.0, busy=100.0, scan_hz=3.5, pose_hz=2.5)
    est = CostEstimates(testbed_ch, 0.0, 300.0)
    learn(est, amcl_out(testbed_ch), [starved] * 10, settled=lambda i: i != amcl)
    assert est.live(amcl, laptop, 2.0) == 36.0
    for n in range(10):                             # received 3 s before: older than 2 s
        est.observe(laptop_reports(n * 0.2, **starved), amcl_out(testbed_ch), n * 0.2 + 3.0,
                    2.0, lambda i: True)
    assert est.live(amcl, laptop, 5.0) == 36.0
    for n in range(10):
        r = laptop_reports(n * 0.2, **starved)
        r["laptop"] = replace(r["laptop"], running={})
        est.observe(r, amcl_out(testbed_ch), n * 0.2, 2.0, lambda i: True)
    assert est.live(amcl, laptop, 2.0) == 36.0


def test_the_filter_ignores_a_report_seen_before():
    f = CostFilter(36.0, 0.0, 0.0)
    for _ in range(5):
        f.observe(1.0, 80.0, False)
    assert f.samples == 1 and f.value(1.0) == 36.0


def test_a_hold_keeps_the_estimate_until_it_ends_and_relaxation_runs_from_there():
    f = CostFilter(12.0, 0.0, 100.0)
    for n in range(MEDIAN_OF):
        f.observe(n * 0.5, 82.0, True)
    left = (MEDIAN_OF - 1) * 0.5
    f.hold(left + 10.0, left + 90.0)                 # sent back 10 s after its last sample
    held = 12.0 + 70.0 * math.exp(-0.1)
    assert f.value(left + 50.0) == pytest.approx(held)
    assert f.value(left + 90.0) == pytest.approx(held)
    assert f.value(left + 190.0) == pytest.approx(12.0 + (held - 12.0) / math.e)
    f.observe(left + 200.0, 40.0, False)             # back there: what it believes then
    assert f.measured == pytest.approx(12.0 + (held - 12.0) * math.exp(-1.1))
    assert f.held == (math.inf, math.inf)
