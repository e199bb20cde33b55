"""The host speed a calibration's quota holds for (quota_for_the_day.py): what --normalise-cpu
follows from when the quota was found for the moment (--robot-cpu auto)."""
import json

from anyscale_testbed.quota_calibration import QuotaPoint
from anyscale_testbed.quota_for_the_day import (host_cpu_ms_measured, host_speed_found_at,
                                                read_calibration, write_calibration)
from anyscale_testbed.testbed_record import TestbedRecord


def test_a_runs_host_speed_is_the_median_after_its_start_up():
    rec = TestbedRecord(cpu_normalisation=[(5.0, 0.3, 0.9, 30.0), (25.0, 0.3, 0.9, 12.0),
                                           (30.0, 0.3, 0.9, 11.0), (35.0, 0.3, 0.9, 13.0)])
    assert host_cpu_ms_measured(rec, skip_s=20.0) == 12.0
    # A run shorter than its start-up: every measurement it has.
    assert host_cpu_ms_measured(rec, skip_s=100.0) == 12.5
    assert host_cpu_ms_measured(TestbedRecord()) is None


def test_the_kept_quota_holds_for_the_run_that_measured_it():
    points = [QuotaPoint(0.34, 2.9), QuotaPoint(0.28, 2.1)]
    assert host_speed_found_at(0.28, points, [10.0, 12.0]) == 12.0
    assert host_speed_found_at(0.28, points, [10.0, None]) is None


def test_an_unmeasured_last_step_holds_for_the_runs_its_fit_used():
    points = [QuotaPoint(0.34, 2.9), QuotaPoint(0.25, 1.6), QuotaPoint(0.30, 2.5)]
    assert host_speed_found_at(0.27, points, [10.0, None, 14.0]) == 12.0
    assert host_speed_found_at(0.27, points, [None, None, None]) is None


def test_the_calibration_file_keeps_its_host_speed_and_reads_older_files(tmp_path):
    path = str(tmp_path / "calibration.json")
    write_calibration(path, 0.28, [QuotaPoint(0.28, 2.1)], 11.5)
    assert read_calibration(path) == (0.28, [QuotaPoint(0.28, 2.1)], 11.5)
    with open(path, "w") as f:
        json.dump({"robot_cpu": 0.3, "points": [[0.3, 2.0]]}, f)        # before host_cpu_ms
    assert read_calibration(path) == (0.3, [QuotaPoint(0.3, 2.0)], None)
    with open(path, "w") as f:
        f.write("[1, 2]")
    assert read_calibration(path) is None
