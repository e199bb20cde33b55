"""Run metrics: path length, the paper's mean angular velocity, localisation error; CSV/PNG."""
import math

import numpy as np
import pytest

from anyscale_nav_demo import results
from anyscale_nav_demo.occupancy_map import OccupancyMap


def test_metrics_on_a_known_trajectory():
    t = np.linspace(0, 10, 101)
    yaw = np.linspace(0, math.pi, 101)          # half a turn in 10 s: 18 deg/s
    assert results.mean_abs_angular_velocity_deg(t, yaw) == pytest.approx(18.0)
    wrapped = (yaw * 3 + math.pi) % (2 * math.pi) - math.pi   # 1.5 turns through +-pi: 54 deg/s
    assert results.mean_abs_angular_velocity_deg(t, wrapped) == pytest.approx(54.0)
    assert results.path_length([[0, 0], [3, 4], [3, 5]]) == pytest.approx(6.0)


def test_localisation_error_interpolates_truth():
    truth_t = np.array([0.0, 1.0, 2.0])
    truth = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    est_t = np.array([0.5, 1.5, 5.0])           # the last is outside the truth: dropped
    est = np.array([[0.5, 0.3], [1.5, -0.4], [9.0, 9.0]])
    assert results.localisation_errors(truth_t, truth, est_t, est) == pytest.approx([0.3, 0.4])


def test_writes_csv_and_png(tmp_path):
    truth = [(0.0, 0.0, 0.0, 0.0), (1.0, 1.0, 0.0, 0.0)]
    s = results.summary(truth, truth, 0.0, 1.0, 5, [0, 1, 2, 3])
    assert s["loc_error_rms_m"] == 0.0 and s["time_to_complete_s"] == 1.0
    results.write_csv(str(tmp_path / "s.csv"), [list(s.values())], list(s.keys()))
    assert (tmp_path / "s.csv").read_text().startswith("time_to_complete_s,")
    results.plot_path(str(tmp_path / "p.png"), OccupancyMap(np.zeros((20, 20)), 0.1), truth, truth)
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"
