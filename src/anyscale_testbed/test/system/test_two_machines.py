"""The two commands a user runs on two real machines, verbatim, one in each network namespace of
the test bed (root: namespaces, cgroups; conftest.py skips without them):
    robot:  roslaunch anyscale_nav_demo robot.launch uplink_interface:=<its veth>
    laptop: roslaunch anyscale_nav_demo laptop.launch
each with ROS_MASTER_URI at the robot's address and ROS_IP at its own, as the nav demo README's
"Two real machines" section tells a user to set them. AMCL must start on the robot, move to the
laptop, and come home when the link is cut, its laptop instance ending by its lease. Where AMCL
runs is read from /proc (which network namespace its process is in), not from the decision
node's word. A run should take about a minute; its waits allow at most about four."""
import os
import time

import pytest

from anyscale_core.model_loader import load_model
from anyscale_core.polling import wait_for

from anyscale_testbed.calibration_file import calibrated_cores, nav_demo_path
from anyscale_testbed.testbed_monitor_ros import node_processes
from anyscale_testbed.testbed_session import NamespaceBed, TestbedSession, layout_with_cpu

ROBOT_UP_S = 90.0       # master, agent, decision node, then every node of the model on the robot
MOVE_OUT_S = 60.0       # the link must hold AMCL's bandwidth for bandwidth_hold_s first
RETURN_S = 10.0         # the robot's agent sees the carrier go at once
LEASE_END_S = 10.0      # lease_s 3 + the agent's SIGINT grace 2 + margin


def tail(path, chars=3000):
    try:
        with open(path, errors="replace") as f:
            return f.read()[-chars:]
    except OSError as e:
        return f"({e})"


@pytest.fixture(scope="module")
def two_machines(tmp_path_factory):
    run_dir = str(tmp_path_factory.mktemp("two_machines"))
    model = load_model(nav_demo_path("config", "testbed.yaml"))
    amcl_names = {model.instance_name("amcl", s).lstrip("/"): "amcl" for s in model.scale_names}
    # The laptop at its calibrated quota, so that its agent measures its own load rather than
    # the whole box's. The robot runs unlimited: its roslaunch also runs the simulator (this
    # robot's hardware), which the calibrated robot quota leaves out.
    laptop_cores = calibrated_cores(nav_demo_path("config", "testbed_calibration.yaml"))[1]
    seen = {}
    with NamespaceBed(layout_with_cpu(0.0, laptop_cores)) as bed:
        session = TestbedSession(bed, run_dir)
        master_uri = session.env("robot")["ROS_MASTER_URI"]
        robot_ns, laptop_ns = bed.netns_link("robot"), bed.netns_link("laptop")

        def amcl_in():
            return sorted(node_processes(amcl_names, master_uri)["amcl"])

        def log(name):
            return tail(os.path.join(run_dir, "logs", f"{name}.log"))

        # The robot's command brings up its master (ROS_MASTER_URI names its own address).
        robot = session.roslaunch("robot", "robot", [
            "anyscale_nav_demo", "robot.launch",
            f"uplink_interface:={bed.uplink_interface('robot')}"], wait_for_master=False)
        seen["first"] = wait_for(amcl_in, ROBOT_UP_S, 0.2)
        assert seen["first"] == [robot_ns], \
            f"AMCL never ran on the robot alone: {seen['first']}\n" + log("robot")
        # A user starts the laptop once the robot is up, with the command as it is: no --wait.
        laptop = session.roslaunch("laptop", "laptop", ["anyscale_nav_demo", "laptop.launch"],
                                   wait_for_master=False)
        seen["out"] = wait_for(lambda: amcl_in() == [laptop_ns], MOVE_OUT_S, 0.2)
        assert seen["out"], f"AMCL never ran on the laptop alone: {amcl_in()}\n" \
                            + log("robot") + log("laptop")
        bed.set_link(False)
        cut = time.monotonic()
        seen["home"] = wait_for(lambda: robot_ns in amcl_in(), RETURN_S, 0.05)
        seen["home_s"] = time.monotonic() - cut
        seen["alone"] = wait_for(lambda: amcl_in() == [robot_ns], LEASE_END_S, 0.1)
        seen["alone_s"] = time.monotonic() - cut
        bed.set_link(True)
        seen["running"] = {"robot": robot.poll() is None, "laptop": laptop.poll() is None}
        seen["logs"] = log("robot") + log("laptop")
    return seen


def test_amcl_starts_on_the_robot_and_moves_to_the_laptop(two_machines):
    assert two_machines["out"]


def test_a_cut_link_brings_amcl_home(two_machines):
    assert two_machines["home"], f"AMCL not on the robot {RETURN_S:g} s after the cut\n" \
                                 + two_machines["logs"]


def test_the_laptop_instance_ends_by_its_lease_behind_the_cut(two_machines):
    assert two_machines["alone"], f"AMCL still on the laptop {two_machines['alone_s']:.1f} s " \
                                  "after the cut\n" + two_machines["logs"]


def test_both_commands_keep_running_through_it(two_machines):
    assert two_machines["running"] == {"robot": True, "laptop": True}, two_machines["logs"]
