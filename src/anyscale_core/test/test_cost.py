"""Eq. 1 (Perf of a mapping) and Eq. 2 (its integral over a run)."""
import numpy as np
import pytest

from anyscale_core.cost import ObjectiveIntegrator, perf, perf_of_many


def test_perf_all_on_robot_is_sum_of_robot_cpu(testbed, testbed_ch):
    assert perf(testbed_ch, testbed_ch.initial_mapping()) == pytest.approx(
        sum(n.cpu_usage["robot"] for n in testbed.nodes))


def test_perf_with_amcl_on_laptop(testbed_ch):
    assign = testbed_ch.initial_mapping()
    assign[testbed_ch.node_index("amcl")] = testbed_ch.scale_index("laptop")
    base = perf(testbed_ch, testbed_ch.initial_mapping())
    assert perf(testbed_ch, assign) == pytest.approx(base - 50 * 1.0 + 36 * 3.5)


def test_perf_of_many_matches_perf(testbed_ch):
    rows = np.stack([testbed_ch.initial_mapping()] * 3)
    rows[1, testbed_ch.node_index("amcl")] = 1
    rows[2, testbed_ch.node_index("ar_recognition")] = 1
    assert perf_of_many(testbed_ch, rows).tolist() == pytest.approx(
        [perf(testbed_ch, r) for r in rows])


def test_objective_sums_time_weighted_perf():
    obj = ObjectiveIntegrator(start_time=10.0, start_perf=100.0)
    obj.change(20.0, 200.0)       # 10 s at 100
    obj.change(25.0, 50.0)        # 5 s at 200
    assert obj.total(30.0) == pytest.approx(10 * 100 + 5 * 200 + 5 * 50)
    assert obj.mean_perf(30.0) == pytest.approx((1000 + 1000 + 250) / 20)


def test_objective_rejects_time_going_back():
    obj = ObjectiveIntegrator(0.0, 1.0)
    obj.change(5.0, 2.0)
    with pytest.raises(ValueError):
        obj.change(4.0, 3.0)
    with pytest.raises(ValueError):
        obj.total(1.0)
