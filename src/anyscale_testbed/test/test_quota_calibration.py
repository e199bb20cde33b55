"""The robot's quota for the day: the steps towards AMCL's 2-2.3 Hz with every node home."""
import math

import pytest

from anyscale_testbed.quota_calibration import (QUOTA_BOUNDS, TARGET_HZ, CalibrationError,
                                                QuotaPoint, calibrate_quota, next_quota,
                                                settled)


def test_the_first_step_scales_the_cpu_left_over_by_the_other_nodes():
    # 3.27 Hz at 0.34 cores (the main command on 2026-11-25): 0.12 + 0.22 x 2.15 / 3.27.
    assert TARGET_HZ == pytest.approx(2.15)
    assert next_quota([QuotaPoint(0.34, 3.27)]) == pytest.approx(0.265, abs=1e-3)
    assert next_quota([QuotaPoint(0.34, 1.5)]) > 0.34


def test_later_steps_fit_the_proportional_model_to_every_measurement():
    # A machine exactly on the model: 10 Hz per spare core; the fit finds it from any points.
    points = [QuotaPoint(0.34, 2.2), QuotaPoint(0.28, 1.6)]
    assert next_quota(points) == pytest.approx(0.335)
    # The readings of 2026-11-27 (the secant had no usable slope): the fit averages them.
    noisy = [QuotaPoint(0.254, 2.25), QuotaPoint(0.239, 2.32), QuotaPoint(0.223, 1.53)]
    assert 0.235 < next_quota(noisy) < 0.25


def test_a_step_stays_within_the_bounds():
    assert next_quota([QuotaPoint(0.34, 50.0)]) == QUOTA_BOUNDS[0]
    assert next_quota([QuotaPoint(0.34, 0.05)]) == QUOTA_BOUNDS[1]


def test_calibration_stops_once_settled_and_says_so():
    lines = []

    def machine(q):
        return 2.0 * (q - 0.10) / 0.17                    # 2 Hz at 0.27 cores
    quota, points = calibrate_quota(0.34, machine, lines.append)
    assert [p.quota for p in points][0] == 0.34 and quota == points[-1].quota
    assert settled(points[-1]) and not settled(points[0]) and len(points) <= 3
    assert "kept" in lines[-1] and "next 0.288 cores" in lines[0]


@pytest.mark.parametrize("hz, kept", [(1.85, False), (1.99, False), (2.0, True), (2.3, True),
                                      (2.35, False)])
def test_only_a_robot_that_alone_sustains_amcls_minimum_and_little_more_is_kept(hz, kept):
    # 1.85 Hz at home broke AMCL's 2 s tolerance with nothing moving (tolerance bench, run 4).
    assert settled(QuotaPoint(0.25, hz)) == kept


def test_calibration_gives_up_after_its_runs_with_the_last_step_unmeasured():
    lines = []
    noisy = iter([3.0, 1.0, 3.0]).__next__
    quota, points = calibrate_quota(0.34, lambda q: noisy(), lines.append, max_runs=3)
    assert len(points) == 3 and quota == next_quota(points)
    assert "not settled after 3 runs" in lines[-1] and "unmeasured" in lines[-1]


def test_a_host_too_slow_for_the_premise_ends_at_the_upper_bound_after_one_run_there():
    # 2026-11-28, the main command: 0.64 Hz at 0.34 cores, 1.83 Hz at 0.8, then 0.8 again.
    lines, measured = [], []
    readings = {0.34: 0.64, QUOTA_BOUNDS[1]: 1.83}
    quota, points = calibrate_quota(0.34, lambda q: measured.append(q) or readings[q],
                                    lines.append)
    assert measured == [0.34, QUOTA_BOUNDS[1]] and quota == QUOTA_BOUNDS[1]
    assert "next 0.8 cores" in lines[0]
    assert "1.83 Hz at home, below" in lines[-1] and "upper bound" in lines[-1]
    assert "too slow for the premise" in lines[-1] and "off the premise" in lines[-1]


def test_a_host_too_fast_for_the_premise_ends_at_the_lower_bound():
    lines = []
    quota, points = calibrate_quota(QUOTA_BOUNDS[0], lambda q: 4.0, lines.append)
    assert quota == QUOTA_BOUNDS[0] and len(points) == 1
    assert "above" in lines[-1] and "lower bound" in lines[-1] and "too fast" in lines[-1]


@pytest.mark.parametrize("hz", [math.nan, 0.0])
def test_a_run_without_amcl_rate_stops_the_calibration(hz):
    with pytest.raises(CalibrationError, match="at 0.34 cores gave no AMCL rate"):
        calibrate_quota(0.34, lambda q: hz, lambda line: None)
