"""Who had the CPU while a topic was silent (soak_cpu.py), on synthetic census samples: the
cores per process and CPU group over the span, a process started in it, the words that tell a
robot held back from outside its quota from one whose quota went to a neighbour."""
import pytest

from anyscale_testbed.soak_cpu import cpu_during, describe_cpu
from anyscale_testbed.soak_invariants import CensusSample

ROBOT, LAPTOP = "/anyscale_robot", "/anyscale_laptop"
QUOTAS = {ROBOT: ("robot", 0.34), LAPTOP: ("laptop", 1.2)}


def sample(t, cpu):
    return CensusSample(t, {}, {}, 0, [list(c) for c in cpu])


def test_cores_per_process_over_the_samples_around_the_span():
    census = [sample(10.0, [("amcl", ROBOT, 11, 5.0), ("odometry", ROBOT, 12, 2.0)]),
              sample(10.5, [("amcl", ROBOT, 11, 5.1), ("odometry", ROBOT, 12, 2.05)]),
              sample(11.5, [("amcl", ROBOT, 11, 5.3), ("odometry", ROBOT, 12, 2.1),
                            ("roscore", "/", 40, 0.4)])]      # started in the span
    span, used = cpu_during(census, 10.2, 11.1)
    assert span == pytest.approx(1.5)
    assert used[(ROBOT, "amcl")] == pytest.approx(0.2)
    assert used[(ROBOT, "odometry")] == pytest.approx(0.1 / 1.5)
    assert used[("/", "roscore")] == pytest.approx(0.4 / 1.5)


def test_a_robot_held_back_from_outside_reads_below_its_quota():
    census = [sample(74.5, [("ar_recognition", ROBOT, 20, 1.0), ("ekf", ROBOT, 21, 1.0),
                            ("world_sim", "/", 30, 9.0)]),
              sample(76.5, [("ar_recognition", ROBOT, 20, 1.02), ("ekf", ROBOT, 21, 1.3),
                            ("world_sim", "/", 30, 10.0), ("rosmaster", "/", 41, 0.3),
                            ("roscore", "/", 40, 0.5)])]
    line = describe_cpu(*cpu_during(census, 75.0, 76.3), QUOTAS)
    assert line == ("over 2.0 s: robot 0.16 of 0.34 cores (ekf 0.15, ar_recognition 0.01); "
                    "outside the quotas 0.90 cores (world_sim 0.50, roscore 0.25, "
                    "rosmaster 0.15)")


def test_a_span_no_two_samples_enclose_says_so():
    census = [sample(10.0, [("amcl", ROBOT, 11, 5.0)])]
    assert cpu_during(census, 9.0, 9.5) == (0.0, {})
    assert describe_cpu(0.0, {}, QUOTAS) == "no CPU sample spans it"


def test_the_words_go_below_the_violations_in_the_table():
    from anyscale_testbed.soak_report import format_table
    table = format_table([], [], [], [], ["CPU while /ar_markers silent: over 2.0 s: ..."])
    assert "CPU while /ar_markers silent: over 2.0 s: ..." in table.splitlines()


def test_a_process_is_named_by_its_node_name_or_its_program():
    import os
    from anyscale_testbed.proc_census import _name, cpu_usage
    name, cgroup, seconds = cpu_usage(os.getpid())
    assert name and cgroup.startswith("/") and seconds >= 0
    assert _name(["/usr/bin/python3", "/opt/x/amcl", "__name:=amcl__laptop"]) == "amcl__laptop"
    assert _name(["/usr/bin/python3", "-u", "/usr/bin/roscore", "-p", "1"]) == "roscore"
    assert _name(["/usr/bin/python3", "-m", "pytest"]) == "pytest"
    assert _name(["/usr/lib/ros/rosout", "__name:=rosout"]) == "rosout"
    assert _name([]) == "?"


def test_a_judged_soak_says_who_had_the_cpu_in_each_silence(tmp_path):
    from anyscale_testbed import fault_schedule as fs
    from anyscale_testbed.soak_invariants import SoakModel
    from anyscale_testbed.soak_run import judge
    from anyscale_testbed.testbed_record import TestbedRecord
    rec = TestbedRecord()
    rec.outputs, rec.tolerances = {"ar_recognition": "/ar_markers"}, {"/ar_markers": 1.0}
    rec.receipts = {"/ar_markers": [t / 10 for t in range(0, 750)] + [76.3, 76.4, 90.0]}
    rec.finished_t = 90.0
    model = SoakModel("robot", ["ar_recognition"], set(),
                      {("ar_recognition", "robot"): "/ar_recognition"}, 3.0)
    census = [dict(t=t, instances={"ar_recognition": ["robot"]}, supervisors={}, processes=9,
                   cpu=[["ar_recognition", ROBOT, 20, t / 100]]) for t in (70.0, 74.5, 76.5, 89.0)]
    fault = fs.Fault(74.9, fs.RESTART_ROSCORE)
    data = {"seed": 3, "minutes": 0.5, "schedule": [vars(fault)], "leaks": [],
            "injected": [dict(fault=vars(fault), t=74.9, end=76.0, detail="", error="")],
            "census": census, "resources": [], "quotas": {ROBOT: ["robot", 0.34]}}
    assert judge(str(tmp_path), data, rec, model) == 1
    md = (tmp_path / "fault_soak.md").read_text()
    assert "- CPU while /ar_markers silent 1.40 s > Δ 1 s from t=74.9 s: over 2.0 s: robot " \
           "0.01 of 0.34 cores (ar_recognition 0.01)" in md
