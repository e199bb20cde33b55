#!/usr/bin/python3
"""Benchmark (prints, asserts nothing; root for the test bed): `anyscale profile` of AMCL and AR
recognition on the calibrated two-scale test bed, beside testbed.yaml's values (the paper's
Table II for the robot, derived for the laptop) and bench_cpu_calibration.py's figures.

It brings up the test bed as the main job does (network namespaces, the calibrated cgroup CPU
quotas of testbed_calibration.yaml, the world simulator outside any quota, a clean 27 Mbit/s
link), but with the agents alone: robot.launch decision:=false on the robot, laptop.launch on
the laptop. Then it runs, in the robot's namespace and outside its quota (the command is the
engineer's tool, not part of the robot's load):

    anyscale profile COPY_OF_testbed.yaml --nodes amcl,ar_recognition --json

which starts every node on the robot through its agent, measures AMCL and AR there, then each
alone on the laptop. The model copy with the figures written in is kept in --out.

    sudo -E /usr/bin/python3 tests/bench/bench_profile.py
    sudo -E /usr/bin/python3 tests/bench/bench_profile.py --warmup 10 --window 60 --robot-cpu 0.37
"""
import argparse
import datetime
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "anyscale_testbed", "src"))
from anyscale_testbed.testbed_session import (LoopbackBed, NamespaceBed,  # noqa: E402
                                              TestbedSession, layout_with_cpu)
from anyscale_testbed.two_scale_testbed import missing_capabilities  # noqa: E402

DEMO = os.path.join(ROOT, "src", "anyscale_nav_demo")
MODEL = os.path.join(DEMO, "config", "testbed.yaml")
CALIBRATION = os.path.join(DEMO, "config", "testbed_calibration.yaml")
ANYSCALE = os.path.join(ROOT, "src", "anyscale_core", "scripts", "anyscale")
# bench_cpu_calibration.py, testbed_calibration.yaml (2026-11-21), % of one core: the robot case
# at 0.35 and 0.37 cores (every node in the robot's group, nice 0, no agents), the laptop case
# at 0.9 (AMCL and AR together in the laptop's group).
CALIBRATION_FIGURES = {("amcl", "robot"): "8.4 @0.35, 9.5 @0.37",
                       ("ar_recognition", "robot"): "16.6 @0.35, 16.9 @0.37",
                       ("amcl", "laptop"): "14.6 @0.9", ("ar_recognition", "laptop"): "45.5 @0.9"}


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--warmup", type=float, default=10.0, help="profile --warmup (10 s)")
    p.add_argument("--window", type=float, default=30.0, help="profile --window (30 s)")
    p.add_argument("--robot-cpu", type=float, default=None, help="robot quota, cores "
                                                                 "(default: calibrated)")
    p.add_argument("--laptop-cpu", type=float, default=None, help="laptop quota, cores "
                                                                  "(default: calibrated)")
    p.add_argument("--out", default=os.path.join(ROOT, "results", "bench_profile"),
                   help="where the profiled model copy, the logs and profile.json go")
    return p.parse_args(argv)


def json_at_end(text: str):
    """The JSON object profile prints last: the bed's start_session merges the command's
    standard error (its plan and per-window lines, shown here) into its output."""
    start = text.index("\n{") + 1 if not text.startswith("{") else 0
    print(text[:start], end="")
    return json.loads(text[start:])


def raise_interrupt(*_):
    raise KeyboardInterrupt


def main(argv=None) -> int:
    args = parse_args(argv)
    with open(CALIBRATION) as f:
        calibration = yaml.safe_load(f)
    robot_cpu = args.robot_cpu or float(calibration["robot_cpu_cores"])
    laptop_cpu = args.laptop_cpu or float(calibration["laptop_cpu_cores"])
    out = os.path.join(args.out, datetime.datetime.now().strftime("%Y%m%d-%H%M%S"))
    os.makedirs(out)
    model = os.path.join(out, "testbed_profiled.yaml")
    shutil.copy(MODEL, model)
    missing = missing_capabilities()
    if missing:
        log("this machine lacks " + "; ".join(missing) + ": both scales on loopback, NO CPU "
            "quotas (the figures are then this machine's, not the test bed's)")
    bed = LoopbackBed() if missing else NamespaceBed(layout_with_cpu(robot_cpu, laptop_cpu))
    signal.signal(signal.SIGTERM, raise_interrupt)     # a plain kill still tears the bed down
    with bed:
        session = TestbedSession(bed, out)
        session.roslaunch("robot", "world", [
            "anyscale_testbed", "testbed_world.launch", f"model:={model}", "link:=schedule",
            "schedule:=[[0, 27]]", f"record_path:={os.path.join(out, 'record.json')}",
            f"results_dir:={os.path.join(out, 'nav')}"], cpu_quota=False,
            wait_for_master=False)
        session.roslaunch("robot", "robot", [
            "anyscale_nav_demo", "robot.launch", "sim:=false", "record:=false",
            "decision:=false", f"model:={model}",
            f"uplink_interface:={bed.uplink_interface('robot')}"])
        session.roslaunch("laptop", "laptop", ["anyscale_nav_demo", "laptop.launch",
                                               f"model:={model}"])
        time.sleep(10)     # the master, the simulator and both agents come up
        log(f"quotas robot {robot_cpu:g} / laptop {laptop_cpu:g} cores; anyscale profile "
            f"--warmup {args.warmup:g} --window {args.window:g}")
        profile = bed.start("robot", ["/usr/bin/python3", ANYSCALE, "profile", model, "--nodes",
                                      "amcl,ar_recognition", "--warmup", str(args.warmup),
                                      "--window", str(args.window), "--json"],
                            session.env("robot"), None, cpu_quota=False,
                            stdout=subprocess.PIPE)
        stdout, _ = profile.communicate()
    if profile.returncode != 0:
        log(f"anyscale profile failed (exit {profile.returncode}); logs in {out}/logs")
        return 1
    result = json_at_end(stdout.decode(errors="replace"))
    with open(os.path.join(out, "profile.json"), "w") as f:
        json.dump(result, f, indent=2)
    with open(MODEL) as f:
        paper = {n["name"]: n["cpu_usage"] for n in yaml.safe_load(f)["nodes"]}
    print("\n| node | scale | profile: % of the scale (its capacity) | % of one core (sd) | "
          "output | testbed.yaml (paper) | bench_cpu_calibration, % of one core |")
    print("|---|---|---|---|---|---|---|")
    for m in result["measurements"]:
        rates = ", ".join(f"{t} {hz:.2f} Hz" for t, hz in m["output_rates_hz"].items())
        print(f"| {m['node']} | {m['scale']} | {m['cpu_usage']:g} % ({m['capacity_cores']:g} "
              f"cores) | {m['cpu_percent_of_one_core']:.1f} ({m['cpu_sd']:.1f}) | {rates} | "
              f"{paper[m['node']].get(m['scale'], '-')} % | "
              f"{CALIBRATION_FIGURES.get((m['node'], m['scale']), '-')} |")
    print(f"\nmemory_mb: {result['memory_mb']}; model with the figures: {model}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
