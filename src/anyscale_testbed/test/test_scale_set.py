"""run_testbed.py --scales (scale_set.py, demo_launch.py), no root: the scale sets and the
server's quota, whether the quotas fit this host, the model each set runs, the bed's layout,
the launches on each scale (the two-scale ones as they were, plus the server's agent), and
main() up to the bed's set-up (nothing is started)."""
import argparse
import os

import pytest

from anyscale_testbed import demo_run
from anyscale_testbed.access_point_layout import AccessPointLayout
from anyscale_testbed.demo_launch import launch_demo, remote_launch_args, wifi_peer_args
from anyscale_testbed.demo_run import parse_args
from anyscale_testbed.scale_set import (SERVER_CPU_CORES, THREE_SCALES, TWO_SCALES, bed_layout,
                                        fit_problem, model_problem, parse_scales, quota_words,
                                        scale_cores, slow_day_server_cores)
from anyscale_testbed.slow_host import LAPTOP_FIXED_CORES
from anyscale_testbed.two_scale_testbed import TwoScaleError, TwoScaleLayout

CONFIG = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", "..",
                                       "anyscale_nav_demo", "config"))


def test_the_scale_sets_and_a_bad_one_in_one_line():
    assert parse_args([], "out").scales == TWO_SCALES
    assert parse_args(["--scales", "robot, laptop,server"], "out").scales == THREE_SCALES
    with pytest.raises(ValueError, match="--scales: expected robot,laptop or "
                                         "robot,laptop,server, got 'robot,server'"):
        parse_scales("robot,server")


@pytest.mark.parametrize("argv,message", [
    (["--scales", "laptop,robot"], "--scales: expected robot,laptop or robot,laptop,server"),
    (["--server-cpu", "0.5"], "--server-cpu: the server's quota; it needs --scales "
                              "robot,laptop,server"),
    (["--scales", "robot,laptop,server", "--server-cpu", "3"],
     "--server-cpu: expected 0.05 to 2 cores, got 3"),
])
def test_bad_scale_options_are_one_line_and_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as ended:
        parse_args(argv, "out")
    assert ended.value.code == 2
    assert message in capsys.readouterr().err


def test_the_server_quota_defaults_and_grows_in_the_slow_day_mode_as_the_laptops():
    args = parse_args(["--scales", "robot,laptop,server"], "out")
    assert args.server_cpu is None and SERVER_CPU_CORES == 0.5
    assert parse_args(["--scales", "robot,laptop,server", "--server-cpu", "0.4"],
                      "out").server_cpu == 0.4
    assert scale_cores(0.34, 0.9) == {"robot": 0.34, "laptop": 0.9}
    assert list(scale_cores(0.34, 0.9, 0.5)) == ["robot", "laptop", "server"]
    assert slow_day_server_cores(0.5, 1.0) == 0.5
    assert slow_day_server_cores(0.5, 3.0) == pytest.approx(0.5 + 2 * LAPTOP_FIXED_CORES)


def test_the_quotas_must_leave_the_world_room_on_this_host():
    assert fit_problem({"robot": 0.34, "laptop": 0.9, "server": 0.5}, 2) == ""
    problem = fit_problem({"robot": 0.4, "laptop": 0.9, "server": 0.6}, 2)
    assert "add up to 1.90 cores" in problem and "this host's 2 CPUs" in problem
    assert "lower --server-cpu or --laptop-cpu" in problem and "\n" not in problem


def test_the_start_lines_quotas_are_the_two_scale_ones_with_a_server_added():
    assert quota_words({"robot": 0.34, "laptop": 0.9}) == "CPU quota robot 0.34 / laptop 0.9 cores"
    assert quota_words(scale_cores(0.34, 0.9, 0.5)) == (
        "CPU quota robot 0.34 / laptop 0.9 / server 0.5 cores")


def test_each_set_has_its_layout():
    two = bed_layout({"robot": 0.34, "laptop": 0.9}, "coverage")
    assert isinstance(two, TwoScaleLayout) and two.laptop.cpu_cores == 0.9
    three = bed_layout(scale_cores(0.34, 0.9, 0.5), "coverage")
    assert isinstance(three, AccessPointLayout)
    assert [e.cpu_cores for e in three.ends] == [0.34, 0.9, 0.5]
    assert three.wired_commands()
    assert bed_layout(scale_cores(0.34, 0.9, 0.5), "unshaped").wired_commands() == []


def test_a_model_given_must_have_the_sets_scales(tmp_path):
    three = os.path.join(CONFIG, "testbed_three_scales.yaml")
    two = os.path.join(CONFIG, "testbed.yaml")
    assert model_problem(three, THREE_SCALES) == ""
    assert model_problem(two, TWO_SCALES) == ""
    problem = model_problem(two, THREE_SCALES)
    assert "its scales are robot,laptop, the bed's (--scales) robot,laptop,server" in problem
    assert "config/testbed_three_scales.yaml" in problem
    assert model_problem(str(tmp_path / "none.yaml"), THREE_SCALES).startswith("--model: ")


class Session:
    """Records each roslaunch: (scale, log name, argv)."""

    def __init__(self):
        self.launched = []

    def roslaunch(self, scale, name, argv, **_):
        self.launched.append((scale, name, argv))
        return name


class Bed:
    def __init__(self, layout=None):
        if layout is not None:
            self.layout = layout

    def uplink_interface(self, scale):
        return "asv_robot"


def launches(argv, bed):
    session = Session()
    args = parse_args(argv, "out")
    world = launch_demo(session, bed, args, "M.yaml", (7.4, 5.9, 0.0), None, "/r/record.json",
                        "/r", "coverage")
    assert world == "world"
    return session.launched


def test_two_scales_launch_the_world_the_robot_and_the_laptop_as_they_always_did():
    launched = launches([], Bed(TwoScaleLayout()))
    assert [(s, n) for s, n, _ in launched] == [("robot", "world"), ("robot", "robot"),
                                                ("laptop", "laptop")]
    assert launched[2][2] == ["anyscale_nav_demo", "laptop.launch", "model:=M.yaml",
                              "warm_start:=true", "respawn:=false"]
    assert not any(a.startswith("wifi_peer") for a in launched[0][2])
    assert "uplink_interface:=asv_robot" in launched[1][2]
    assert launches([], Bed()) == launched          # loopback: no layout, the same launches


def test_three_scales_add_the_servers_agent_and_point_the_shaper_at_the_access_point():
    layout = bed_layout(scale_cores(0.34, 0.9, 0.5), "coverage")
    launched = launches(["--scales", "robot,laptop,server"], Bed(layout))
    assert [(s, n) for s, n, _ in launched] == [("robot", "world"), ("robot", "robot"),
                                                ("laptop", "laptop"), ("server", "server")]
    assert launched[3][2] == ["anyscale_nav_demo", "laptop.launch", "model:=M.yaml",
                              "warm_start:=true", "respawn:=false", "scale:=server"]
    assert launched[0][2][-2:] == ["wifi_peer_namespace:=anyscale_ap",
                                   "wifi_peer_interface:=asv_ap_robot"]
    two_world = launches([], Bed(TwoScaleLayout()))[0][2]
    assert launched[0][2][:-2] == two_world         # otherwise the same world


def test_remote_launch_args_and_the_wifi_peer_alone():
    assert remote_launch_args("laptop", "m", "false", True)[-2:] == [
        "warm_start:=false", "respawn:=true"]
    assert remote_launch_args("server", "m", "true", False)[-1] == "scale:=server"
    assert wifi_peer_args(argparse.Namespace()) == []


class BedStoppedBeforeSetUp:
    """Stands in for NamespaceBed: keeps the layout main() built, and ends the run on entry."""
    built = []

    def __init__(self, layout, **_):
        self.layout, self.quotas = layout, {}
        BedStoppedBeforeSetUp.built.append(layout)

    def __enter__(self):
        raise TwoScaleError("stopped before the bed was set up")

    def __exit__(self, *_):
        return False


@pytest.fixture
def main_to_the_bed(monkeypatch, tmp_path):
    """demo_run.main up to the bed's set-up, on a 2-CPU host with the calibrated quotas."""
    monkeypatch.setattr(demo_run, "missing_capabilities", lambda: [])
    monkeypatch.setattr(demo_run, "quota_cores", lambda robot, laptop: (0.34, 0.9))
    monkeypatch.setattr(demo_run, "world_start", lambda *_: ((7.4, 5.9, 0.0), None))
    monkeypatch.setattr(demo_run, "nav_demo_path",
                        lambda *parts: os.path.join(os.path.dirname(CONFIG), *parts))
    monkeypatch.setattr(demo_run, "NamespaceBed", BedStoppedBeforeSetUp)
    monkeypatch.setattr(demo_run.signal, "signal", lambda *_: None)
    monkeypatch.setattr(demo_run.os, "cpu_count", lambda: 2)
    BedStoppedBeforeSetUp.built = []
    return lambda *argv: demo_run.main(str(tmp_path), "run_testbed.py",
                                       list(argv) + ["--out", str(tmp_path)])


def test_main_builds_each_sets_bed_with_its_quotas(main_to_the_bed, capsys):
    assert main_to_the_bed() == 1
    assert main_to_the_bed("--scales", "robot,laptop,server") == 1
    two, three = BedStoppedBeforeSetUp.built
    assert isinstance(two, TwoScaleLayout) and [e.cpu_cores for e in two.ends] == [0.34, 0.9]
    assert isinstance(three, AccessPointLayout)
    assert [e.cpu_cores for e in three.ends] == [0.34, 0.9, 0.5]
    out = capsys.readouterr().out
    assert "CPU quota robot 0.34 / laptop 0.9 cores per 100 ms period" in out
    assert "CPU quota robot 0.34 / laptop 0.9 / server 0.5 cores per 100 ms period" in out


def test_main_refuses_quotas_that_do_not_fit_and_a_model_of_other_scales(main_to_the_bed,
                                                                         capsys):
    assert main_to_the_bed("--scales", "robot,laptop,server", "--server-cpu", "0.8") == 2
    assert "add up to 2.04 cores" in capsys.readouterr().err
    assert main_to_the_bed("--scales", "robot,laptop,server", "--model",
                           os.path.join(CONFIG, "testbed.yaml")) == 2
    assert "its scales are robot,laptop" in capsys.readouterr().err
    assert BedStoppedBeforeSetUp.built == []
