"""The robot's quota for the day: the steps towards AMCL's 2 Hz with every node home."""
import math

import pytest

from anyscale_testbed.quota_calibration import (QUOTA_BOUNDS, CalibrationError, QuotaPoint,
                                                calibrate_quota, next_quota, settled)


def test_the_first_step_scales_the_cpu_left_over_by_the_other_nodes():
    # 3.27 Hz at 0.34 cores (the main command on 2026-11-25): 0.12 + 0.22 x 2 / 3.27.
    assert next_quota([QuotaPoint(0.34, 3.27)]) == pytest.approx(0.255, abs=1e-3)
    assert next_quota([QuotaPoint(0.34, 1.5)]) > 0.34


def test_later_steps_follow_the_secant_of_the_last_two():
    points = [QuotaPoint(0.34, 3.0), QuotaPoint(0.28, 2.4)]     # 10 Hz per core
    assert next_quota(points) == pytest.approx(0.24)
    # Read the wrong way round (noise): the proportional step on the last one instead.
    wrong_way = [QuotaPoint(0.30, 2.3), QuotaPoint(0.29, 2.4)]
    assert next_quota(wrong_way) == next_quota(wrong_way[-1:])


def test_a_step_stays_within_the_bounds():
    assert next_quota([QuotaPoint(0.34, 50.0)]) == QUOTA_BOUNDS[0]
    assert next_quota([QuotaPoint(0.34, 0.05)]) == QUOTA_BOUNDS[1]


def test_calibration_stops_once_settled_and_says_so():
    lines = []
    machine = lambda q: 2.0 * (q - 0.10) / 0.17           # 2 Hz at 0.27 cores
    quota, points = calibrate_quota(0.34, machine, lines.append)
    assert [p.quota for p in points] == [0.34, 0.276] and quota == 0.276
    assert settled(points[-1]) and not settled(points[0])
    assert "kept" in lines[-1] and "next 0.276 cores" in lines[0]


def test_calibration_gives_up_after_its_runs_with_the_last_step_unmeasured():
    lines = []
    noisy = iter([3.0, 1.0, 3.0]).__next__
    quota, points = calibrate_quota(0.34, lambda q: noisy(), lines.append, max_runs=3)
    assert len(points) == 3 and quota == next_quota(points)
    assert "not settled after 3 runs" in lines[-1] and "unmeasured" in lines[-1]


@pytest.mark.parametrize("hz", [math.nan, 0.0])
def test_a_run_without_amcl_rate_stops_the_calibration(hz):
    with pytest.raises(CalibrationError, match="at 0.34 cores gave no AMCL rate"):
        calibrate_quota(0.34, lambda q: hz, lambda line: None)
