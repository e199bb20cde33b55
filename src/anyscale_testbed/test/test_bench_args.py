"""The benches' command line for each run (imported from their files under tests/bench; the
benches themselves need root and the test bed): --normalise-cpu reaches run_testbed.py only
when asked for, and the premise bench prints the host's speed a normalised run recorded."""
import importlib.util
import os

import pytest

from anyscale_testbed.testbed_record import TestbedRecord

BENCH_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "tests",
                         "bench")


def fake_testbed(argvs, host_ms=None, home_hz=None):
    """A run_logged for the benches' runs on a machine on which AMCL with every node home runs
    2 Hz at 0.27 cores and 2.82 Hz at 0.34: records the command line in `argvs` and saves a
    record of every node home. host_ms(argvs): the host speed the run timed (none if None);
    home_hz(argv, out_dir): another rate for some runs (None: the machine's)."""
    from test_evaluation_table import on, record

    def run(argv, out_dir):
        argvs.append(argv)
        quota = float(argv[argv.index("--robot-cpu") + 1])
        hz = home_hz(argv, out_dir) if home_hz else None
        rec = record(mappings=[(0.0, on(), 0.0, 0.0)],
                     amcl_hz=hz if hz is not None else 2.0 * (quota - 0.10) / 0.17)
        if host_ms is not None:
            rec.cpu_normalisation = [(60.0, quota, 0.9, host_ms(argvs))]
        os.makedirs(os.path.join(out_dir, "office_floor-fake"))
        rec.save(os.path.join(out_dir, "office_floor-fake", "record.json"))
        return 0
    return run


def on_fake_testbed(bench, monkeypatch, fake_run):
    """The bench's runs and its calibration's go to fake_run, on a machine whose calibration
    file says 0.34 / 0.9 cores and whose world has 5 goals."""
    from anyscale_testbed import quota_for_the_day
    monkeypatch.setattr(bench, "run_logged", fake_run)
    monkeypatch.setattr(quota_for_the_day, "run_logged", fake_run)
    monkeypatch.setattr(quota_for_the_day, "quota_cores", lambda robot, laptop: (0.34, 0.9))
    monkeypatch.setattr(bench, "start_on_the_testbed", lambda program: None)
    if hasattr(bench, "goal_count"):
        monkeypatch.setattr(bench, "goal_count", lambda world: 5)


def load_bench(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(BENCH_DIR, f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def tolerances():
    return load_bench("bench_tolerances")


@pytest.fixture(scope="module")
def premise():
    return load_bench("bench_premise")


def test_the_tolerance_bench_passes_normalise_cpu_only_when_asked_for(tolerances):
    plain = tolerances.parse_args([])
    assert plain.normalise_cpu is False
    argv = tolerances.run_argv(plain, 2, 13, "out/run03")
    assert "--normalise-cpu" not in argv
    assert argv[1] == tolerances.RUN_TESTBED and argv[argv.index("--seed") + 1] == "13"
    assert argv[argv.index("--start-goal") + 1] == "2"
    normalised = tolerances.parse_args(["--normalise-cpu", "--runs", "2"])
    argv = tolerances.run_argv(normalised, 0, 11, "out/run01")
    assert argv.count("--normalise-cpu") == 1 and argv[argv.index("--out") + 1] == "out/run01"


def test_the_tolerance_bench_passes_the_late_boost_only_when_asked_for(tolerances):
    assert "--late-boost-fraction" not in tolerances.run_argv(tolerances.parse_args([]), 0, 11, "o")
    off = tolerances.run_argv(tolerances.parse_args(["--late-boost-fraction", "0"]), 0, 11, "o")
    assert off[off.index("--late-boost-fraction") + 1] == "0"


def test_the_tolerance_bench_runs_at_the_quota_for_the_day_or_the_one_given(tolerances, capsys):
    assert tolerances.parse_args([]).robot_cpu is None          # auto: found before each run
    assert "--robot-cpu" not in tolerances.run_argv(tolerances.parse_args([]), 0, 11, "out/run01")
    given = tolerances.parse_args(["--robot-cpu", "0.27"])
    argv = tolerances.run_argv(given, 0, 11, "out/run01", given.robot_cpu)
    assert argv[argv.index("--robot-cpu") + 1] == "0.27"
    for bad, said in (("0", "expected 0.05 to 2 cores, got 0"), ("lots", "expected cores or auto")):
        with pytest.raises(SystemExit) as ended:
            tolerances.parse_args(["--robot-cpu", bad])
        assert ended.value.code == 2 and f"--robot-cpu: {said}" in capsys.readouterr().err


def test_the_premise_bench_passes_normalise_cpu_only_when_asked_for(premise):
    assert premise.parse_args([]).normalise_cpu is False
    assert premise.parse_args(["--normalise-cpu"]).normalise_cpu is True
    argv = premise.run_argv(0.34, "robot", 150.0, "out/01")
    assert "--normalise-cpu" not in argv and argv[argv.index("--robot-cpu") + 1] == "0.34"
    assert argv[argv.index("--cfs-period-ms") + 1] == "100"
    assert argv[argv.index("--record-inputs") + 1] == "/joint_states"
    argv = premise.run_argv(0.34, "robot", 150.0, "out/01", period_ms=10.0)
    assert argv[argv.index("--cfs-period-ms") + 1] == "10"
    argv = premise.run_argv(None, "robot", 150.0, "out/01", normalise_cpu=True)
    assert argv.count("--normalise-cpu") == 1 and "--robot-cpu" not in argv


def test_the_premise_bench_runs_each_quota_at_each_cfs_period(premise, capsys):
    assert premise.parse_args([]).periods == [100.0]
    assert premise.parse_args(["--cfs-period-ms", "100,10"]).periods == [100.0, 10.0]
    with pytest.raises(SystemExit):
        premise.parse_args(["--cfs-period-ms", "0.5"])
    assert "--cfs-period-ms: expected 1 to 1000 ms each" in capsys.readouterr().err


def test_the_premise_bench_states_the_host_speed_of_a_normalised_run(premise):
    assert premise.host_speed_line(TestbedRecord()) == ""
    rec = TestbedRecord(cpu_normalisation=[(0.0, 0.34, 0.9, 15.5), (5.0, 0.36, 0.95, 16.4),
                                           (10.0, 0.35, 0.93, 16.0)], reference_cpu_ms=15.5)
    assert premise.host_speed_line(rec) == ("    host workload 16.0 ms median (15.5-16.4; "
                                            "reference 15.5), robot quota 0.340-0.360 cores")


def test_the_tolerance_bench_records_the_inputs_of_amcl_unless_told_not_to(tolerances):
    argv = tolerances.run_argv(tolerances.parse_args([]), 0, 11, "out/run01")
    assert argv[argv.index("--record-inputs") + 1] == "/scan,/joint_states,/odom,/odometry/filtered"
    argv = tolerances.run_argv(tolerances.parse_args(["--record-inputs", ""]), 0, 11, "out/run01")
    assert "--record-inputs" not in argv


@pytest.mark.parametrize("bench", ["bench_tolerances", "bench_premise"])
def test_the_benches_help_prints_and_exits_0(bench, capsys):
    with pytest.raises(SystemExit) as ended:
        load_bench(bench).parse_args(["--help"])
    assert ended.value.code == 0
    assert "--normalise-cpu" in capsys.readouterr().out


def test_the_tolerance_bench_finds_the_quota_before_each_run(tolerances, tmp_path, monkeypatch,
                                                             capsys):
    argvs = []
    on_fake_testbed(tolerances, monkeypatch, fake_testbed(argvs))
    out = tmp_path / "bench"
    tolerances.main(["--runs", "2", "--out", str(out)])
    assert [os.path.relpath(a[a.index("--out") + 1], out) for a in argvs] == [
        "run01-calibration/run1", "run01-calibration/run2", "run01", "run02-calibration/run1",
        "run02"]
    assert [a[a.index("--robot-cpu") + 1] for a in argvs] == [
        "0.34", "0.288", "0.288", "0.288", "0.288"]
    assert "[1/2] start at goal 0, seed 11, robot 0.288 cores" in capsys.readouterr().out
    # The calibration runs record what the runs record: the same load on the robot's quota.
    assert all(a[a.index("--record-inputs") + 1] == tolerances.DEFAULT_INPUTS for a in argvs)
    # Records without a timed host speed (older runs): no reference, "-".
    assert "| run02-calibration | 0.288 | 0.288 cores: 2.21 Hz | - |" in (
        out / "tolerances.md").read_text()


def test_the_tolerance_bench_normalises_from_each_calibrations_host_speed(tolerances, tmp_path,
                                                                          monkeypatch):
    argvs = []
    on_fake_testbed(tolerances, monkeypatch,
                    fake_testbed(argvs, host_ms=lambda runs: 10.0 + len(runs)))  # 11, 12 ms...
    out = tmp_path / "bench"
    tolerances.main(["--runs", "2", "--normalise-cpu", "--out", str(out)])
    runs = [a for a in argvs if "calibration" not in a[a.index("--out") + 1]]
    # Run 1 follows from its calibration's kept run (the 2nd: 12 ms), run 2 from its own (14).
    assert [a[a.index("--reference-cpu-ms") + 1] for a in runs] == ["12.000", "14.000"]
    assert all("--normalise-cpu" in a for a in runs)
    assert not any("--normalise-cpu" in a for a in argvs if a not in runs)
    assert "| run01-calibration | 0.288 | 0.34 cores: 2.82 Hz, 0.288 cores: 2.21 Hz | 12.0 |" in (
        out / "tolerances.md").read_text()


def test_the_host_speed_bench_alternates_fixed_and_normalised_runs_at_the_calibrated_quota(
        tmp_path, monkeypatch, capsys):
    bench = load_bench("bench_host_speed")
    argvs = []
    # The host timed at 12 ms; fixed runs read 1.9 Hz, normalised ones 2.1 (a made-up effect,
    # to follow it through).
    fake_run = fake_testbed(argvs, host_ms=lambda runs: 12.0, home_hz=lambda argv, out_dir: (
        None if "calibration" in out_dir else 2.1 if "--normalise-cpu" in argv else 1.9))
    on_fake_testbed(bench, monkeypatch, fake_run)
    assert bench.main(["--rounds", "2", "--out", str(tmp_path)]) == 0
    runs = [a for a in argvs if "calibration" not in a[a.index("--out") + 1]]
    assert ["--normalise-cpu" in a for a in runs] == [False, True, True, False]
    assert all(a[a.index("--robot-cpu") + 1] == "0.288" for a in runs)
    assert all(a[a.index("--reference-cpu-ms") + 1] == "12.000" for a in runs
               if "--normalise-cpu" in a)
    assert all(a[a.index("--schedule") + 1] == "[[0, 0]]" for a in runs)     # every node home
    printed = capsys.readouterr().out
    # Calibrated at 2.21 Hz: fixed runs 0.31 Hz off, normalised 0.11: the ratio 0.35.
    assert "normalised / fixed, mean deviation from the calibrated rate: 0.35" in printed
    assert (tmp_path / "host_speed.md").exists()


def test_the_host_speed_bench_refuses_a_given_quota_without_its_host_speed(capsys):
    bench = load_bench("bench_host_speed")
    assert bench.parse_args(["--robot-cpu", "0.25", "--reference-cpu-ms", "11"]).robot_cpu == 0.25
    for argv, said in ((["--robot-cpu", "0.25"], "go together"),
                       (["--rounds", "0"], "--rounds: expected 1 to 50"),
                       (["--duration", "40"], "--duration: expected more than")):
        with pytest.raises(SystemExit) as ended:
            bench.parse_args(argv)
        assert ended.value.code == 2 and said in capsys.readouterr().err


def test_the_profile_bench_compares_at_equal_host_speed(tmp_path, monkeypatch):
    import json
    import math
    bench = load_bench("bench_profile")
    # The profile ran while the workload took 7.7 ms, the calibration at 7.0: the host was 10 %
    # slower during the profile, so its figures are scaled by 7.0 / 7.7 to compare.
    assert bench.host_speed_factor(7.0, 7.7) == pytest.approx(0.909, abs=1e-3)
    assert math.isnan(bench.host_speed_factor(7.0, None))
    assert math.isnan(bench.host_speed_factor(float("nan"), 7.7))

    def fake_calibration(argv, log_dir):
        step = {"cpu": {"amcl": 7.7, "ar_recognition": 18.4}, "host_ms": 6.9,
                "rates": {"/amcl_pose": 4.2, "/ar_markers": 17.7}}
        laptop = dict(step, host_ms=None)
        with open(argv[argv.index("--json") + 1], "w") as f:
            json.dump({"robot": [step], "laptop": [laptop]}, f)
        return 0
    monkeypatch.setattr(bench, "run_logged", fake_calibration)
    figures, host_ms = bench.calibration_side_by_side(0.34, 0.9, str(tmp_path))
    assert figures[("amcl", "robot")] == (7.7, 4.2)
    assert host_ms["robot"] == 6.9 and math.isnan(host_ms["laptop"])


def test_the_learning_bench_runs_both_modes_alike_but_for_the_model_costs(monkeypatch, tmp_path):
    from anyscale_testbed.testbed_record import EventRecord
    bench = load_bench("bench_learning")
    argvs = []

    def fake_run(argv, out_dir):
        argvs.append(argv)
        model = "--model-costs" in argv
        done_t = 110.0 if model else 100.0
        rec = TestbedRecord(navigation_status=[(10.0, "goal 1"), (done_t, "done 5/5")])
        rec.events = [EventRecord(20.0, "migrate", "amcl", "robot", "laptop", "room", 0.5, True,
                                  20.0),
                      EventRecord(30.0, "migrate_back", "amcl", "laptop", "robot",
                                  "connection spending its tolerance: laser->amcl", 0.2, True,
                                  30.0)]
        os.makedirs(os.path.join(out_dir, "office_floor-fake"))
        rec.finished_t = 120.0
        rec.save(os.path.join(out_dir, "office_floor-fake", "record.json"))
        return 0
    monkeypatch.setattr(bench, "run_logged", fake_run)
    monkeypatch.setattr(bench, "start_on_the_testbed", lambda program: None)
    monkeypatch.setattr(bench, "quota_cores", lambda robot, laptop: (0.34, 0.9))
    assert bench.main(["--pairs", "2", "--seed", "3", "--out", str(tmp_path)]) == 0
    assert [("--model-costs" in a) for a in argvs] == [False, True, True, False]
    for argv in argvs:
        assert argv[argv.index("--seed") + 1] == "3"
        assert argv[argv.index("--robot-cpu") + 1] == "0.34"
    table = (tmp_path / "learning.txt").read_text()
    assert "pair 1: learning / model path time 0.900; moves 2 / 2" in table
    assert table.splitlines()[1].split() == ["1", "learning", "90.0", "1", "1", "1", "0"]


def test_the_learning_bench_names_a_bad_argument(capsys):
    bench = load_bench("bench_learning")
    with pytest.raises(SystemExit):
        bench.parse_args(["--robot-cpu", "0"])
    assert "--robot-cpu: expected cores > 0, got 0" in capsys.readouterr().err


def test_the_three_scale_bench_runs_both_scale_sets_on_one_seed(monkeypatch, tmp_path):
    from test_evaluation_table import on, record
    bench = load_bench("bench_three_scales")
    argvs = []

    def run(argv, out_dir):
        argvs.append(argv)
        three = "server" in argv[argv.index("--scales") + 1]
        rec = record(mappings=[(5.0, on(), 0.0, 0.0),
                               (30.0, on(amcl="server" if three else "laptop"), 0.0, 0.0),
                               (60.0, on(), 0.0, 0.0)])
        os.makedirs(os.path.join(out_dir, "office_floor-fake"))
        rec.save(os.path.join(out_dir, "office_floor-fake", "record.json"))
        return 0
    monkeypatch.setattr(bench, "run_logged", run)
    monkeypatch.setattr(bench, "start_on_the_testbed", lambda program: None)
    assert bench.main(["--seed", "4", "--robot-cpu", "0.3", "--out", str(tmp_path)]) == 0
    assert [a[a.index("--scales") + 1] for a in argvs] == ["robot,laptop", "robot,laptop,server"]
    assert all(a[a.index("--seed") + 1] == "4" and a[a.index("--robot-cpu") + 1] == "0.3"
               for a in argvs)
    table = (tmp_path / "three_scales.md").read_text()
    # AMCL: 5-30 s and 60-250 s home, 30-60 s out, on the laptop in one run, the server in the other
    assert "| amcl: robot / laptop / server | 215 s / 30 s / - | 215 s / - / 30 s |" in table
    # Recorded already: a second call runs nothing.
    argvs.clear()
    bench.main(["--out", str(tmp_path)])
    assert argvs == []
