"""The WiFi link shaper on the real test bed (root, network namespaces, tc): the settings it
applies are what `tc qdisc show` and `ip link show` report on both ends of the veth, a loss of
coverage takes the link down and a return brings it up at the new rate, and a failing command
is reported with tc's own message. Then the node itself against a private roscore (port 11641,
no rostest): in schedule mode it really shapes the link, and in coverage mode (dry run) it
publishes the model's bandwidth for the true pose, the coverage grid and the access point."""
import json
import os
import shutil
import subprocess
import sys
import time

import pytest

from anyscale_testbed.bench_runs import interrupt_then_kill
from anyscale_testbed.link_shaper import (LinkSetting, SettingTracker, apply_setting,
                                          link_setting_for)
from anyscale_testbed.system_test_gate import NOT_RUN
from anyscale_testbed.two_scale_testbed import (ScaleEnd, TwoScaleError, TwoScaleLayout,
                                                TwoScaleTestbed, missing_capabilities, run)

MISSING = missing_capabilities(need_cgroups=False)
pytestmark = pytest.mark.skipif(bool(MISSING), reason=NOT_RUN + "this machine lacks " +
                                "; ".join(MISSING))

# Its own namespaces and interfaces, so it can run beside the other test-bed tests.
LAYOUT = TwoScaleLayout(
    robot=ScaleEnd("robot", "asls_robot", "asls_r", "10.213.9.1", 0.0),
    laptop=ScaleEnd("laptop", "asls_laptop", "asls_l", "10.213.9.2", 0.0))


def tbf_rate_mbps(end: ScaleEnd) -> float:
    """The root tbf's rate on the end's interface, from `tc -j` (bytes/s), in Mbit/s."""
    out = run(["ip", "netns", "exec", end.namespace, "tc", "-j", "qdisc", "show", "dev",
               end.interface]).stdout
    roots = [q for q in json.loads(out) if q.get("root")]
    assert len(roots) == 1 and roots[0]["kind"] == "tbf", out
    return roots[0]["options"]["rate"] * 8 / 1e6


def admin_up(end: ScaleEnd) -> bool:
    out = run(["ip", "-n", end.namespace, "-j", "link", "show", end.interface]).stdout
    return "UP" in json.loads(out)[0]["flags"]


def link_state():
    """(up, rate) of each end: what the shaper should have made of the link."""
    return [(admin_up(end), round(tbf_rate_mbps(end), 3)) for end in LAYOUT.ends]


def test_settings_reach_tc_and_the_link():
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="asls"):
        tracker = SettingTracker()
        applied = []
        # Along a path: full rate, a lower 802.11g step, coverage lost, back at another step.
        for t, mbps in enumerate([27.0, 27.0, 12.0, 0.0, 0.0, 4.5]):
            wanted = link_setting_for(mbps)
            if tracker.due(wanted, float(t)):
                apply_setting(LAYOUT, tracker.applied, wanted)
                tracker.succeeded(wanted)
                applied.append(mbps)
                if wanted.up:
                    assert link_state() == [(True, mbps)] * 2
                else:
                    # Down on both ends at once; the old qdisc stays (it carries nothing).
                    assert link_state() == [(False, 12.0)] * 2
        assert applied == [27.0, 12.0, 0.0, 4.5]


def test_a_failing_command_names_the_problem():
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="asls"):
        missing = TwoScaleLayout(robot=LAYOUT.robot,
                                 laptop=ScaleEnd("laptop", LAYOUT.laptop.namespace, "asls_none",
                                                 LAYOUT.laptop.address, 0.0))
        with pytest.raises(TwoScaleError, match="asls_none"):
            apply_setting(missing, None, LinkSetting(True, 6.0))
        # The robot end was shaped before the laptop's command failed.
        assert tbf_rate_mbps(LAYOUT.robot) == pytest.approx(6.0)


# --- the node, against a private roscore ------------------------------------------------------

MASTER_PORT = 11641
NODE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "nodes", "link_shaper")
PROBE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "nodes", "link_shaper_probe.py")


@pytest.fixture
def roscore(tmp_path):
    """A roscore of its own on MASTER_PORT; yields the environment for nodes that use it."""
    if shutil.which("roscore") is None:
        pytest.fail("roscore not on PATH: source the workspace's devel/setup.bash")
    env = dict(os.environ, ROS_MASTER_URI=f"http://localhost:{MASTER_PORT}",
               ROS_HOME=str(tmp_path / "ros_home"))
    core = subprocess.Popen(["roscore", "-p", str(MASTER_PORT)], env=env,
                            stdout=open(tmp_path / "roscore.log", "wb"),
                            stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 20
        while subprocess.run(["rosparam", "list"], env=env,
                             capture_output=True).returncode != 0:
            assert core.poll() is None and time.monotonic() < deadline, \
                (tmp_path / "roscore.log").read_text()
            time.sleep(0.3)
        yield env
    finally:
        os.killpg(core.pid, 2)
        core.wait(timeout=20)


def start_node(env, tmp_path, *params):
    """The link_shaper node with private params `name:=value`; its output goes to node.log."""
    return subprocess.Popen([sys.executable, NODE, "__name:=link_shaper_test"] +
                            ["_" + p for p in params], env=env,
                            stdout=open(tmp_path / "node.log", "wb"), stderr=subprocess.STDOUT)


def test_node_follows_its_schedule_on_the_real_link(roscore, tmp_path):
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="asls"):
        node = start_node(roscore, tmp_path, "mode:=schedule",
                          "schedule:=[[0, 9], [1.5, 0], [3.0, 18]]", "rate_hz:=10",
                          "robot_namespace:=asls_robot", "laptop_namespace:=asls_laptop",
                          "robot_interface:=asls_r", "laptop_interface:=asls_l")
        try:
            seen, deadline = [], time.monotonic() + 20
            while time.monotonic() < deadline and (not seen or seen[-1] != [(True, 18.0)] * 2):
                try:
                    state = link_state()
                except AssertionError:
                    state = None            # no tbf yet: the node is still starting
                # Only states where both ends agree: between its commands the node has set
                # one end and not yet the other.
                if state and state[0] == state[1] and (not seen or state != seen[-1]):
                    seen.append(state)
                time.sleep(0.05)
        finally:
            interrupt_then_kill(node, 10)
        log = (tmp_path / "node.log").read_text()
        # Coming back, the rate is set before the link goes up: "down at 18" may be caught
        # in between, "up at 9" never.
        settled = [state for state in seen if state != [(False, 18.0)] * 2]
        assert settled == [[(True, 9.0)] * 2, [(False, 9.0)] * 2, [(True, 18.0)] * 2], log
        assert "wifi: 9.0 Mbit/s at t=0.0 s" in log and "wifi: link down" in log, log


def test_node_publishes_coverage_for_the_true_pose(roscore, tmp_path):
    node = start_node(roscore, tmp_path, "mode:=coverage", "access_point_x:=2.0",
                      "access_point_y:=5.0", "dry_run:=true", "rate_hz:=10")
    try:
        probe = subprocess.run([sys.executable, PROBE, "3.0"], env=roscore, capture_output=True,
                               text=True, timeout=90)
    finally:
        interrupt_then_kill(node, 10)
    log = (tmp_path / "node.log").read_text()
    assert probe.returncode == 0, probe.stderr[-2000:] + log
    seen = json.loads(probe.stdout.strip().splitlines()[-1])
    assert (seen["near"], seen["far"]) == (27.0, 0.0), log
    coverage = seen["coverage"]
    assert (coverage["size"], coverage["resolution"], coverage["frame_id"]) == (
        [20, 20], 0.5, "map")
    assert coverage["max"] == 100 and coverage["min"] >= 0
    assert seen["access_point"] == [2.0, 5.0]
    assert "wifi: 27.0 Mbit/s at (3.00, 5.00)" in log, log
    assert "wifi: link down (no coverage at (300.00, 5.00))" in log, log
    assert "dry run, would run: ip -n anyscale_robot link set asv_robot down" in log, log
