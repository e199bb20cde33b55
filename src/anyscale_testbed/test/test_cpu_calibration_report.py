"""The CPU calibration bench's report (cpu_calibration_report.py; the bench itself needs root
and cgroups): a step's line, the groups' CPU and throttling in each case, the host's speed."""
import argparse

from anyscale_testbed.cpu_calibration_report import (ROBOT_NODES, SIM, TOPICS, print_report,
                                                     qname, step_line)


def result(robot_q, laptop_q, throttle, host_samples):
    return {"robot_q": robot_q, "laptop_q": laptop_q, "rates": {t: 1.5 for t in TOPICS},
            "cpu": {n: 10.0 for n in ROBOT_NODES + [SIM]}, "throttle": throttle, "wall": 30.0,
            "host_ms": 15.5 if host_samples else None, "host_samples": host_samples}


def test_a_step_is_one_line_and_a_quota_of_none_reads_none():
    r = result(0.35, None, {}, [15.0, 16.0])
    assert step_line(r) == ("  /amcl_pose 1.50 Hz, /ar_markers 1.50 Hz, amcl 10.0 %, ar 10.0 % of "
                            "a core, host workload 15.5 ms")
    assert (qname(0.35), qname(0.0)) == ("0.35", "none")


def test_the_report_sums_each_group_and_its_throttling(capsys):
    robot = result(0.35, None, {"anyscale_cal_robot": (100, 25)}, [15.0, 16.0])
    laptop = result(0.35, 0.9, {"anyscale_cal_robot": (100, 25), "anyscale_cal_laptop": (100, 0)},
                    [])
    args = argparse.Namespace(world="office_floor", duration=30.0, amcl_params={}, ar_params={})
    print_report(args, 2, 95.0, "not set", [robot], [laptop])
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("CPU calibration, ") and line.endswith(
        "2 cores, world office_floor, 30 s per step, 95 s total") for line in lines)
    assert any("median 15.5 ms of CPU over the steps (15.0-16.0, 2 measurements)" in line
               and "reference_cpu_ms is not set" in line for line in lines)
    cpu_rows = [line.split() for line in lines if line.startswith("0.35") and "10.0" in line]
    # robot case: every node in the robot group; laptop case: AMCL and AR in their own
    assert cpu_rows[0][-3:] == ["110.0", "-", "25/-"]
    assert cpu_rows[1][-3:] == ["90.0", "20.0", "25/0"]
    assert "  robot 0.35   amcl    9 %  ar    9 %  navigation    9 %" in lines
