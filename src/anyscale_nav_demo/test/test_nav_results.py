"""Run metrics: path length, the paper's mean angular velocity, localisation error; CSV/PNG;
Fig. 5's configurations along the path."""
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


def test_fig5_configurations_and_when_they_held():
    on = lambda amcl, ar: {"amcl": amcl, "ar_recognition": ar, "ekf": "robot"}  # noqa: E731
    assert results.configuration_of(on("laptop", "robot")) == results.AMCL_ON_LAPTOP
    assert results.configuration_of(on("robot", "robot")) == results.BOTH_ON_ROBOT
    assert results.configuration_of(on("laptop", "laptop")) == results.BOTH_ON_LAPTOP
    assert results.configuration_of(on("robot", "laptop")) == results.AR_ON_LAPTOP
    changes = [(10.0, on("laptop", "robot")), (20.0, on("laptop", "laptop"))]
    assert results.configurations_at([5.0, 10.0, 15.0, 25.0], changes) == [
        results.BOTH_ON_ROBOT, results.AMCL_ON_LAPTOP, results.AMCL_ON_LAPTOP,
        results.BOTH_ON_LAPTOP]
    runs = results.configuration_runs([[0, 0], [1, 0], [2, 0], [3, 0]], ["a", "b", "b", "a"])
    assert [(c, p[:, 0].tolist()) for c, p in runs] == [("a", [0]), ("b", [0, 1, 2]),
                                                        ("a", [2, 3])]


def test_path_png_colours_the_true_path_by_configuration(tmp_path):
    import matplotlib.image
    truth = [(float(t), 0.2 + 0.15 * t, 1.0, 0.0) for t in range(12)]
    configurations = [results.BOTH_ON_ROBOT] * 6 + [results.AMCL_ON_LAPTOP] * 6
    results.plot_path(str(tmp_path / "p.png"), OccupancyMap(np.zeros((20, 20)), 0.1), truth,
                      [], "t", configurations)
    image = matplotlib.image.imread(str(tmp_path / "p.png"))[:, :, :3]

    def drawn(colour):
        rgb = np.array([int(colour[i:i + 2], 16) / 255 for i in (1, 3, 5)])
        return int(np.count_nonzero(np.all(np.abs(image - rgb) < 0.02, axis=2)))
    colours = results.CONFIGURATION_COLOURS
    assert drawn(colours[results.BOTH_ON_ROBOT]) > 50
    assert drawn(colours[results.AMCL_ON_LAPTOP]) > 50
    assert drawn(colours[results.BOTH_ON_LAPTOP]) == 0
