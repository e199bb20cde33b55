"""localisation_error.py: the truth interpolated at an estimate's stamp (the thresholds probe
for laser -> AMCL), headings across +-pi, and stamps outside the buffer."""
import math

import pytest

from anyscale_nav_demo.localisation_error import TruthBuffer, position_error


def test_truth_is_interpolated_at_the_estimates_stamp():
    truth = TruthBuffer(horizon_s=10)
    for i in range(21):                       # 0.4 m/s along x, 20 Hz
        truth.add(i * 0.05, i * 0.02, 1.0, 0.0)
    x, y, yaw = truth.at(0.125)
    assert (x, y, yaw) == pytest.approx((0.05, 1.0, 0.0))
    assert position_error((0.05, 1.1), truth.at(0.125)) == pytest.approx(0.1)
    assert truth.at(-0.01) is None and truth.at(1.01) is None


def test_heading_interpolates_the_short_way_round_and_old_poses_leave():
    truth = TruthBuffer(horizon_s=1.0)
    truth.add(0.0, 0, 0, math.pi - 0.1)
    truth.add(1.0, 0, 0, -math.pi + 0.1)
    truth.add(0.5, 9, 9, 0.0)                 # out of order: ignored
    assert abs(math.sin(truth.at(0.5)[2])) == pytest.approx(0.0, abs=1e-9)
    truth.add(2.5, 0, 0, 0.0)
    assert truth.at(0.5) is None
