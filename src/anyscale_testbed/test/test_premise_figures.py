"""The premise bench's figures from synthetic records: rates and speeds per configuration, the
figures with every node home and the flag of a run off the premise."""
import math

import pytest

from anyscale_testbed.premise_figures import (PREMISE_AMCL_HZ, PREMISE_MARGIN_HZ,
                                              configuration_name,
                                              figures_with_every_node_home, format_markdown,
                                              longest_gap_after,
                                              premise_figures, premise_is_off, premise_off_note)
from anyscale_testbed.testbed_record import TestbedRecord

ROBOT = {"amcl": "robot", "ar_recognition": "robot"}
LAPTOP = {"amcl": "laptop", "ar_recognition": "laptop"}


def straight_line(speeds, dt=0.1):
    """Ground truth along x: speeds[(t0, t1)] = v, piecewise."""
    rows, x, t = [], 0.0, 0.0
    for (t0, t1), v in speeds:
        while t < t1:
            rows.append((round(t, 3), x, 0.0))
            x += v * dt
            t += dt
    return rows


def test_rate_speed_and_gap_per_configuration():
    poses = [30 + 0.5 * i for i in range(60)] + [60 + 0.2 * i for i in range(200)]
    poses.remove(40.0)                      # one missed update: a 1 s gap on the robot
    rec = TestbedRecord(mappings=[(0.0, ROBOT, 0.0, 0.0), (60.0, LAPTOP, 0.0, 0.0)],
                        receipts={"/amcl_pose": poses},
                        truth=straight_line([((0, 60), 0.2), ((60, 100), 0.4)]),
                        finished_t=100.0)
    rows = {r["configuration"]: r for r in premise_figures(rec, skip_s=30.0)}
    robot, laptop = rows[configuration_name(ROBOT)], rows[configuration_name(LAPTOP)]
    assert robot["seconds"] == pytest.approx(30.0)
    assert robot["amcl_hz"] == pytest.approx(59 / 30)
    assert robot["amcl_longest_gap_s"] == pytest.approx(1.0)
    assert robot["mean_speed"] == pytest.approx(0.2, abs=0.01)
    assert robot["cruise_speed"] == pytest.approx(0.2, abs=0.01)
    assert laptop["amcl_hz"] == pytest.approx(5.0)
    assert laptop["mean_speed"] == pytest.approx(0.4, abs=0.01)


def test_the_longest_gap_is_between_poses_not_to_a_spans_edge():
    # The start-up cut at 30 s falls 1.8 s before the first pose after it, and the run ends
    # 2.7 s after the last pose: neither is a silence between poses (1.0 s here).
    poses = [28.0] + [31.8 + i for i in range(40)]
    rec = TestbedRecord(mappings=[(0.0, ROBOT, 0.0, 0.0)], receipts={"/amcl_pose": poses},
                        truth=straight_line([((0, 73.5), 0.2)]), finished_t=73.5)
    row = premise_figures(rec, skip_s=30.0)[0]
    assert row["amcl_longest_gap_s"] == pytest.approx(1.0)


def test_short_spans_and_start_up_are_left_out():
    rec = TestbedRecord(mappings=[(0.0, ROBOT, 0, 0), (50.0, LAPTOP, 0, 0), (55.0, ROBOT, 0, 0)],
                        receipts={"/amcl_pose": [float(t) for t in range(100)]},
                        truth=straight_line([((0, 100), 0.1)]), finished_t=100.0)
    rows = premise_figures(rec, skip_s=20.0)
    assert [r["configuration"] for r in rows] == [configuration_name(ROBOT)]
    assert rows[0]["seconds"] == pytest.approx(75.0)       # 20-50 and 55-100


def test_cruise_ignores_standing_still_and_markdown_has_every_row():
    rec = TestbedRecord(mappings=[(0.0, ROBOT, 0, 0)], receipts={"/amcl_pose": [1.0, 2.0]},
                        truth=straight_line([((0, 10), 0.0), ((10, 60), 0.3)]), finished_t=60.0)
    row = premise_figures(rec, skip_s=0.0)[0]
    assert row["mean_speed"] == pytest.approx(0.25, abs=0.01)
    assert row["cruise_speed"] == pytest.approx(0.3, abs=0.01)
    text = format_markdown([{"quota": "0.33", "period_ms": "10", "case": "robot",
                             "joint_states_longest_gap_s": 0.051, **row}])
    assert text.count("\n") == 3 and "| 0.33 | 10 | robot | amcl@robot ar@robot |" in text
    assert text.rstrip().endswith("| 0.051 |")
    assert not math.isnan(row["cruise_speed"])


def test_the_longest_gap_counts_only_after_the_start_up():
    assert longest_gap_after([1.0, 9.0, 10.0, 10.1, 10.4], skip_s=5.0) == pytest.approx(1.0)
    assert longest_gap_after([1.0, 9.0, 10.0, 10.1, 10.4], skip_s=9.5) == pytest.approx(0.3)
    assert math.isnan(longest_gap_after([1.0, 9.0], skip_s=5.0))


def test_the_figures_with_every_node_home_are_that_configurations_row():
    poses = [30 + 0.5 * i for i in range(60)] + [60 + 0.2 * i for i in range(200)]
    rec = TestbedRecord(mappings=[(0.0, ROBOT, 0.0, 0.0), (60.0, LAPTOP, 0.0, 0.0)],
                        receipts={"/amcl_pose": poses},
                        truth=straight_line([((0, 60), 0.2), ((60, 100), 0.4)]),
                        finished_t=100.0)
    home = figures_with_every_node_home(rec, skip_s=30.0)
    assert home["configuration"] == configuration_name(ROBOT)
    assert home["amcl_hz"] == pytest.approx(2.0) and home["cruise_speed"] == pytest.approx(
        0.2, abs=0.01)
    # Never home (or no mapping recorded): nothing to check.
    out = TestbedRecord(mappings=[(0.0, LAPTOP, 0.0, 0.0)], receipts={"/amcl_pose": poses},
                        truth=rec.truth, finished_t=100.0)
    assert figures_with_every_node_home(out, skip_s=30.0) is None
    assert figures_with_every_node_home(TestbedRecord(), skip_s=30.0) is None


def test_a_run_is_off_the_premise_beyond_the_margin_either_way():
    assert (PREMISE_AMCL_HZ, PREMISE_MARGIN_HZ) == (2.0, 0.5)
    for on_premise in (2.0, 1.6, 2.4, 2.5, 1.5, math.nan):
        assert not premise_is_off(on_premise) and premise_off_note(on_premise) == ""
    for off in (2.6, 3.04, 1.4, 5.0):
        assert premise_is_off(off)
    assert premise_off_note(3.04) == "premise off: AMCL 3.0 Hz at home"
    assert premise_off_note(1.2) == "premise off: AMCL 1.2 Hz at home"


def test_the_end_table_states_the_premise_per_configuration_and_flags_a_robot_off_it():
    from anyscale_testbed.testbed_figures import premise_lines

    def run(home_period):
        poses = ([30 + home_period * i for i in range(int(30 / home_period))]
                 + [60 + 0.2 * i for i in range(200)])
        return TestbedRecord(mappings=[(0.0, ROBOT, 0.0, 0.0), (60.0, LAPTOP, 0.0, 0.0)],
                             receipts={"/amcl_pose": poses},
                             truth=straight_line([((0, 60), 0.2), ((60, 100), 0.4)]),
                             finished_t=100.0)
    on = premise_lines(run(0.5))
    assert len(on) == 3 and "premise: AMCL 2 Hz with every node on the robot" in on[0]
    home = next(line for line in on if configuration_name(ROBOT) in line)
    assert "AMCL 2.00 Hz" in home and "cruise 0.20 m/s" in home and "premise off" not in home
    laptop = next(line for line in on if configuration_name(LAPTOP) in line)
    assert "AMCL 5.00 Hz" in laptop and "cruise 0.40 m/s" in laptop
    off = premise_lines(run(1 / 3))           # a host fast enough for AMCL at 3 Hz at home
    assert "premise off: AMCL 3.0 Hz at home" in next(
        line for line in off if configuration_name(ROBOT) in line)
    assert premise_lines(TestbedRecord()) == []
