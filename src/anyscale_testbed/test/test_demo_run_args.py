"""scripts/run_testbed.py's arguments (anyscale_testbed.demo_run.parse_args): the WiFi seed,
--normalise-cpu and the calibration's reference_cpu_ms it needs."""
import pytest

from anyscale_testbed import demo_run
from anyscale_testbed.demo_launch import robot_launch_args
from anyscale_testbed.demo_run import parse_args


def test_seed_defaults_to_the_deterministic_model_and_passes_through():
    assert parse_args([], "out").seed == 0
    assert parse_args(["--seed", "3"], "out").seed == 3


@pytest.mark.parametrize("argv,message", [
    (["--seed", "-1"], "--seed: expected an integer >= 0"),
    (["--seed", "2", "--link", "schedule"], "--seed varies the coverage model"),
    (["--seed", "x"], "--seed: invalid int value"),
])
def test_a_bad_seed_is_one_line_and_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as ended:
        parse_args(argv, "out")
    assert ended.value.code == 2
    assert message in capsys.readouterr().err


def test_the_cfs_period_is_the_kernels_unless_asked_for_and_within_its_limits(capsys):
    assert parse_args([], "out").cfs_period_ms == 100
    assert parse_args(["--cfs-period-ms", "10"], "out").cfs_period_ms == 10
    with pytest.raises(SystemExit) as ended:
        parse_args(["--cfs-period-ms", "0.5"], "out")
    assert ended.value.code == 2
    assert "--cfs-period-ms: expected 1 to 1000 ms (the kernel's limits), got 0.5" in \
        capsys.readouterr().err


def test_normalise_cpu_is_off_unless_asked_for():
    assert parse_args([], "out").normalise_cpu is False
    assert parse_args(["--normalise-cpu"], "out").normalise_cpu is True


def test_the_reference_comes_from_the_calibration_and_its_absence_is_one_line(tmp_path, capsys):
    from anyscale_testbed.calibration_file import calibrated_reference_ms
    good = tmp_path / "good.yaml"
    good.write_text("reference_cpu_ms: 15.5\nrobot_cpu_cores: 0.34\n")
    assert calibrated_reference_ms(str(good)) == 15.5
    for name, text in (("old.yaml", "robot_cpu_cores: 0.34\n"),
                       ("zero.yaml", "reference_cpu_ms: 0\n")):
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(SystemExit) as ended:
            calibrated_reference_ms(str(path))
        assert "--normalise-cpu" in str(ended.value) and "reference_cpu_ms" in str(ended.value)


def test_the_workspace_calibration_has_a_reference():
    import os
    from anyscale_testbed.calibration_file import calibrated_reference_ms
    here = os.path.dirname(os.path.abspath(__file__))
    path = os.path.join(here, "..", "..", "anyscale_nav_demo", "config",
                        "testbed_calibration.yaml")
    assert 10.0 < calibrated_reference_ms(path) < 25.0


def test_the_start_line_states_the_quotas_and_when_they_start_to_follow_the_host():
    from anyscale_testbed.demo_run import NORMALISE_SETTLE_S, normaliser_state
    from anyscale_testbed.host_speed import CpuNormaliser

    class Quota:
        def set_cores(self, cores):
            pass

    n = CpuNormaliser({"robot": Quota(), "laptop": Quota()}, {"robot": 0.34, "laptop": 0.9},
                      15.5, measure=lambda: 17.05, log=lambda line: None,
                      settle_s=NORMALISE_SETTLE_S)
    assert normaliser_state(n) == ("host speed: CPU quota robot 0.340, laptop 0.900 cores, as "
                                   "calibrated, until the nodes have run 30 s; then every 5 s, "
                                   "from the workload's median CPU ms (calibrated at 15.5 ms)")


def test_record_inputs_are_a_list_of_topics_and_a_bad_one_is_one_line(capsys):
    assert parse_args([], "out").record_inputs == []
    assert parse_args(["--record-inputs", "/scan, /odom,"], "out").record_inputs == [
        "/scan", "/odom"]
    with pytest.raises(SystemExit) as ended:
        parse_args(["--record-inputs", "/scan,odom"], "out")
    assert ended.value.code == 2
    assert "--record-inputs: expected resolved topic names such as /scan, got 'odom'" in \
        capsys.readouterr().err


def test_help_prints_and_exits_0(capsys):
    with pytest.raises(SystemExit) as ended:
        parse_args(["--help"], "out")
    assert ended.value.code == 0
    assert "--record-inputs" in capsys.readouterr().out


def test_robot_cpu_is_the_calibration_files_cores_or_auto(capsys):
    default = parse_args([], "out")
    assert default.robot_cpu is None and default.calibrate_robot_cpu is False
    auto = parse_args(["--robot-cpu", "auto"], "out")
    assert auto.robot_cpu is None and auto.calibrate_robot_cpu is True
    # run_demo.sh passes auto first: a user's quota after it wins, without a calibration.
    given = parse_args(["--robot-cpu", "auto", "--robot-cpu", "0.3"], "out")
    assert given.robot_cpu == 0.3 and given.calibrate_robot_cpu is False
    for bad, message in (("fast", "expected cores or auto, got 'fast'"),
                         ("9", "expected 0.05 to 2 cores, got 9")):
        with pytest.raises(SystemExit) as ended:
            parse_args(["--robot-cpu", bad], "out")
        assert ended.value.code == 2
        assert message in capsys.readouterr().err


def test_normalise_cpu_follows_the_host_speed_the_quota_was_found_at(capsys):
    # auto measures its own reference (its calibration run's), a given quota takes one given.
    both = parse_args(["--robot-cpu", "auto", "--normalise-cpu"], "out")
    assert both.normalise_cpu and both.calibrate_robot_cpu and both.reference_cpu_ms is None
    given = parse_args(["--robot-cpu", "0.3", "--normalise-cpu", "--reference-cpu-ms", "9.8"],
                       "out")
    assert given.reference_cpu_ms == 9.8
    for argv, said in ((["--reference-cpu-ms", "9.8"], "9.8 without --normalise-cpu"),
                       (["--normalise-cpu", "--reference-cpu-ms", "0"], "got 0"),
                       (["--robot-cpu", "auto", "--normalise-cpu", "--reference-cpu-ms", "9"],
                        "--robot-cpu auto measures its own")):
        with pytest.raises(SystemExit) as ended:
            parse_args(argv, "out")
        assert ended.value.code == 2
        assert said in capsys.readouterr().err


def test_loops_are_one_unless_asked_for_and_bounded(capsys):
    assert parse_args([], "out").loops == 1
    assert parse_args(["--loops", "2"], "out").loops == 2
    with pytest.raises(SystemExit) as ended:
        parse_args(["--loops", "0"], "out")
    assert ended.value.code == 2
    assert "--loops: expected 1 to 100, got 0" in capsys.readouterr().err


def test_robot_cpu_auto_runs_the_calibration_with_the_runs_own_options(tmp_path, monkeypatch,
                                                                       capsys):
    import os
    from anyscale_testbed import demo_run, quota_for_the_day
    from test_evaluation_table import on, record
    argvs = []

    def fake_run(argv, out_dir):
        """A host on which AMCL runs 2 Hz at home at 0.25 cores and 3.4 Hz at 0.34."""
        argvs.append(argv)
        quota = float(argv[argv.index("--robot-cpu") + 1])
        rec = record(mappings=[(0.0, on(), 0.0, 0.0)], amcl_hz=2.0 + (quota - 0.25) / 0.09 * 1.4)
        # The host's speed as the run timed it: 12 ms of workload, 11 in the second run; the
        # first 20 s (the start-up) do not count.
        ms = 12.0 if len(argvs) == 1 else 11.0
        rec.cpu_normalisation = [(5.0, quota, 0.9, 30.0)] + [(t, quota, 0.9, ms)
                                                             for t in (40.0, 45.0, 50.0)]
        os.makedirs(os.path.join(out_dir, "office_floor-fake"))
        rec.save(os.path.join(out_dir, "office_floor-fake", "record.json"))
        return 0
    monkeypatch.setattr(quota_for_the_day, "run_logged", fake_run)
    monkeypatch.setattr(quota_for_the_day, "quota_cores", lambda robot, laptop: (0.34, 0.9))
    args = parse_args(["--robot-cpu", "auto", "--cfs-period-ms", "50", "--model", "my.yaml"],
                      "out")
    quota, found_at_ms = demo_run.quota_for_this_moment("run_testbed.py", args, str(tmp_path))
    assert 0.23 < quota < 0.27
    assert found_at_ms == 11.0          # the run that measured the quota kept
    assert len(argvs) == 2 and all(a[a.index("--cfs-period-ms") + 1] == "50" for a in argvs)
    assert all(a[a.index("--model") + 1] == "my.yaml" for a in argvs)
    assert all(a[a.index("--schedule") + 1] == "[[0, 0]]" for a in argvs)   # every node home
    printed = capsys.readouterr().out.splitlines()
    assert all(line.startswith(demo_run.PREFIX) for line in printed)
    assert any("calibration run 2 (at most 3)" in line for line in printed)
    assert (tmp_path / "robot_quota" / "calibration.json").exists()


def test_loops_repeat_the_loop_from_where_the_robot_starts():
    from anyscale_testbed.demo_run import world_start
    start, goals = world_start("small_loop")
    assert goals is None                      # navigation reads the world's own goals
    start2, twice = world_start("small_loop", None, 2)
    half = len(twice) // 2
    assert start2 == start and len(twice) % 2 == 0 and twice[:half] == twice[half:]
    assert twice[-1][:3] == start             # the world's last goal is its start
    at1, loop = world_start("small_loop", 1, 3)
    assert len(loop) == 3 * (len(twice) // 2) and loop[-1][:3] == at1


def test_the_holds_and_the_late_boost_reach_robot_launch_only_when_given():
    assert robot_launch_args(parse_args([], "out")) == []
    assert robot_launch_args(parse_args(["--hold-after-loss", "30", "--amcl-hold-after-loss",
                                         "20", "--late-boost-fraction", "0"], "out")) == [
        "late_boost_fraction:=0", "hold_after_loss_s:=30.0",
        "node_hold_after_loss_s:={amcl: 20.0}"]
    assert robot_launch_args(parse_args(["--model-costs"], "out")) == ["learn_costs:=false"]


def test_a_late_boost_fraction_outside_0_1_is_one_line(capsys):
    with pytest.raises(SystemExit) as ended:
        parse_args(["--late-boost-fraction", "1.5"], "out")
    assert ended.value.code == 2
    assert "--late-boost-fraction: expected 0-1, got 1.5" in capsys.readouterr().err


def test_the_weak_link_reaches_robot_launch_only_when_given(capsys):
    assert robot_launch_args(parse_args(["--weak-link-mbps", "0"], "out")) == [
        "weak_link_mbps:=0"]
    with pytest.raises(SystemExit):
        parse_args(["--weak-link-mbps", "-1"], "out")
    assert "--weak-link-mbps: expected 0 or more Mbit/s, got -1" in capsys.readouterr().err


def test_no_forecast_reaches_robot_launch_only_when_given():
    assert "link_forecast:=false" not in robot_launch_args(parse_args([], "out"))
    assert robot_launch_args(parse_args(["--no-forecast"], "out")) == ["link_forecast:=false"]
    # A scheduled link follows the clock, not the place: a link map would mislead.
    for link in ("schedule", "unshaped"):
        assert robot_launch_args(parse_args(["--link", link], "out")) == ["link_forecast:=false"]


def test_a_link_map_to_start_from_must_load_else_one_line(tmp_path, capsys):
    from anyscale_core.link_map import LinkMap
    good = str(tmp_path / "link_map.yaml")
    m = LinkMap()
    m.add("laptop", 1.8e9, 1.0, 1.0, 20.0, False)
    m.save(good)
    assert parse_args(["--link-map", good], "out").link_map == good
    for bad, says in ((str(tmp_path / "none.yaml"), "none.yaml: no such file"),
                      (__file__, "expected a mapping")):
        with pytest.raises(SystemExit) as ended:
            parse_args(["--link-map", bad], "out")
        assert ended.value.code == 2
        assert f"--link-map: {bad}" in capsys.readouterr().err


def test_the_learned_map_is_copied_where_asked(tmp_path, capsys):
    from anyscale_testbed.demo_run import LINK_MAP, keep_link_map
    keep_link_map(str(tmp_path), str(tmp_path / "kept.yaml"))
    assert "the run saved no link map" in capsys.readouterr().out
    (tmp_path / LINK_MAP).write_text("format: anyscale_link_map\n")
    keep_link_map(str(tmp_path), str(tmp_path / "kept.yaml"))
    assert (tmp_path / "kept.yaml").read_text() == "format: anyscale_link_map\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.yaml", LINK_MAP]


@pytest.mark.parametrize("ended_by, cut_short", [("done", False), ("duration", False),
                                                 ("", False), ("shutdown", True)])
def test_a_run_cut_short_by_its_world_is_named_a_failure(tmp_path, ended_by, cut_short):
    """roslaunch exits 0 when a required node dies: the record says how the run ended."""
    from anyscale_testbed.testbed_record import TestbedRecord
    path = str(tmp_path / "record.json")
    TestbedRecord(world="small_loop", finished_t=2.0, ended_by=ended_by).save(path)
    why = demo_run.ended_early(path)
    assert bool(why) == cut_short, why
    if cut_short:
        assert "after 2.0 s" in why and "required node of the world" in why


def test_a_run_without_a_readable_record_is_named_a_failure(tmp_path):
    why = demo_run.ended_early(str(tmp_path / "record.json"))
    assert "no readable record" in why and "record.json" in why
