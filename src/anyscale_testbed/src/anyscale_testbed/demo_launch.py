"""The navigation demo's launches on a test bed (demo_run.py's run, the fault soak's): where the
robot starts and its goals, the world launch on the robot's side, robot.launch, and each remote
scale's laptop.launch (the laptop's; on three scales the server's too, with `scale:=server`),
with the console lines of the world launch that a run shows. The argv lists are built here and
started through testbed_session.TestbedSession; nothing here needs root."""
import json
import os
import sys
from typing import List, Optional

import yaml

from anyscale_core.learned_costs import FILE_NAME as LEARNED_COSTS
from anyscale_nav_demo.goal_sequence import loop_from_goal
from anyscale_testbed.access_point_layout import AccessPointLayout
from anyscale_testbed.calibration_file import nav_demo_path
from anyscale_testbed.scale_set import TWO_SCALES
from anyscale_testbed.slow_host import SlowDayMode, mode_world_args
from anyscale_testbed.testbed_figures import colour_violations
from anyscale_testbed.testbed_session import TestbedSession
from anyscale_testbed.two_scale_testbed import WORLD_NICE

PREFIX = "[testbed] "
# The decision node's link map in each run's directory: loaded at its start, saved during it.
LINK_MAP = "link_map.yaml"
# The end table marks a silence longer than its tolerance with the word VIOLATION; on a
# terminal its line is red as well (the log file keeps the plain word). NO_COLOR turns it off.
COLOUR = sys.stdout.isatty() and "NO_COLOR" not in os.environ


def world_start(world: str, start_goal=None, loops: int = 1):
    """(x, y, yaw) where the robot starts, and navigation's goals: the world's start and None
    (navigation reads the world's goals itself), or with `start_goal` K, goal K's pose and the
    loop from there; with `loops` > 1 the goals repeated that many times."""
    path = nav_demo_path("maps", f"{world}_world.yaml")
    try:
        with open(path) as f:
            world_file = yaml.safe_load(f)
        start = [float(v) for v in world_file["start"]]
        goals = [[float(v) for v in g] for g in world_file["goals"]]
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as e:
        sys.exit(f"run_testbed: --world {world}: cannot read the start pose and goals from "
                 f"{path}: {e}")
    if start_goal is None:
        return start, (goals * loops if loops > 1 else None)
    try:
        start, loop = loop_from_goal(goals, start_goal)
    except ValueError as e:
        sys.exit(f"run_testbed: --start-goal: {world}'s {e}")
    return list(start), [list(g) for g in loop] * loops


def write_calibration(run_dir: str, mode: SlowDayMode) -> str:
    """The slow-day mode's calibration file, written into run_dir; returns its path."""
    path = os.path.join(run_dir, "calibration_host_factor.yaml")
    os.makedirs(run_dir, exist_ok=True)
    with open(path, "w") as f:
        f.write(f"# testbed_calibration.yaml for a host {mode.factor:.2f} x slower than the "
                "reference day (run_testbed.py --host-factor)\n")
        yaml.safe_dump(mode.calibration, f, sort_keys=False)
    return path


def robot_launch_args(args) -> List[str]:
    """robot.launch's holds after a link loss, late boost, weak link, link forecast and learning
    that the run's options set (none: its own)."""
    out = []
    if args.late_boost_fraction is not None:
        out.append(f"late_boost_fraction:={args.late_boost_fraction:g}")
    if args.hold_after_loss is not None:
        out.append(f"hold_after_loss_s:={args.hold_after_loss}")
    if args.amcl_hold_after_loss is not None:
        out.append(f"node_hold_after_loss_s:={{amcl: {args.amcl_hold_after_loss}}}")
    if args.model_costs:
        out.append("learn_costs:=false")
    if getattr(args, "weak_link_mbps", None) is not None:
        out.append(f"weak_link_mbps:={args.weak_link_mbps:g}")
    # The link map assumes that the link follows the robot's place, as coverage does; a
    # scheduled link follows the clock, and what a map learned of it would mislead.
    if getattr(args, "no_forecast", False) or getattr(args, "link", "coverage") != "coverage":
        out.append("link_forecast:=false")
    return out


def remote_launch_args(scale: str, model: str, warm: str, respawn: bool) -> List[str]:
    """roslaunch's arguments on a remote scale: laptop.launch, which runs that scale's agent
    only (the decision node on the robot asks it to start nodes). The laptop's are those of the
    two-scale bed; another scale names itself with `scale:=`."""
    return (["anyscale_nav_demo", "laptop.launch", f"model:={model}", f"warm_start:={warm}",
             f"respawn:={str(respawn).lower()}"]
            + ([] if scale == "laptop" else [f"scale:={scale}"]))


def wifi_peer_args(bed) -> List[str]:
    """testbed_world.launch's args for the link shaper's far end of the WiFi: none on the
    two-scale bed (the laptop's veth end, the launch's default) and on loopback; the access
    point's end of the robot's veth on the three-scale bed."""
    layout = getattr(bed, "layout", None)
    if not isinstance(layout, AccessPointLayout):
        return []
    peer = layout.wifi_link.laptop
    return [f"wifi_peer_namespace:={peer.namespace}", f"wifi_peer_interface:={peer.interface}"]


def launch_demo(session: TestbedSession, bed, args, model: str, start, goals, record: str,
                run_dir: str, link: str, master_running: bool = False, respawn: bool = False,
                echo=None, record_critical: bool = False, mode: Optional[SlowDayMode] = None):
    """The demo's launches on the bed: the world on the robot's side outside its CPU quota (it
    brings up the master unless `master_running`), robot.launch, and laptop.launch on each
    remote scale of `args.scales` (the laptop's; the server's too on three scales).
    `args` are demo_run.parse_args' (world, schedule, seed, duration, rviz, allocator,
    hysteresis, hold_after_loss, amcl_hold_after_loss, cold_start, scales); `respawn`: roslaunch
    starts the agents and the decision node again when they end (the fault soak); `echo` gets
    each line of the world launch (default: the monitor's lines and errors to the console);
    `record_critical`: the monitor records the critical connections' topics too; `mode`: the
    slow-day mode's world and calibration (written into run_dir). Returns the world launch's
    process: the run ends with it."""
    x, y, yaw = start
    warm = str(not args.cold_start).lower()
    world = session.roslaunch(
        "robot", "world", [
            "anyscale_testbed", "testbed_world.launch", f"world:={args.world}",
            f"x:={x}", f"y:={y}", f"yaw:={yaw}", f"model:={model}", f"link:={link}",
            f"schedule:={json.dumps(yaml.safe_load(args.schedule))}",
            f"seed:={args.seed}",
            f"record_path:={record}", f"results_dir:={os.path.join(run_dir, 'nav')}",
            f"duration_s:={args.duration}", f"rviz:={str(args.rviz).lower()}",
            f"record_critical:={str(record_critical).lower()}",
            f"record_inputs:={json.dumps(args.record_inputs)}"]
        + [f"{k}:={v}" for k, v in (mode_world_args(mode) if mode else {}).items()]
        + wifi_peer_args(bed),
        cpu_quota=False, wait_for_master=master_running, echo=echo or echo_monitor_lines,
        nice=WORLD_NICE)
    # The world launch runs the simulator and the recorder outside the robot's quota.
    session.roslaunch("robot", "robot", [
        "anyscale_nav_demo", "robot.launch", "sim:=false", "record:=false",
        f"world:={args.world}", f"x:={x}", f"y:={y}", f"yaw:={yaw}", f"model:={model}",
        f"allocator:={args.allocator}", f"hysteresis_s:={args.hysteresis}",
        f"uplink_interface:={bed.uplink_interface('robot')}", f"warm_start:={warm}",
        f"respawn:={str(respawn).lower()}", f"link_map_file:={os.path.join(run_dir, LINK_MAP)}",
        f"learned_costs_out:={os.path.join(run_dir, LEARNED_COSTS)}"]
        + ([f"goals:={json.dumps(goals)}"] if goals else [])
        + ([f"calibration:={write_calibration(run_dir, mode)}"] if mode else [])
        + robot_launch_args(args))
    for scale in getattr(args, "scales", TWO_SCALES)[1:]:
        session.roslaunch(scale, scale, remote_launch_args(scale, model, warm, respawn))
    return world


def echo_monitor_lines(line: str):
    if line.startswith(PREFIX) or "[ERROR]" in line or "[FATAL]" in line:
        print(colour_violations(line, COLOUR), flush=True)
