#!/usr/bin/python3
"""Benchmark (prints, asserts nothing): Table I's laser -> AMCL row found by `anyscale thresholds`
on the navigation demo's simulator, with AMCL's position error against ground truth as the probe.

Runs the demo on this machine (no namespaces or quotas: the subscriber under test must not be
short of CPU, or the rate it is fed would not be what limits it), on a roscore of its own on a
free port, with the robot's agent alone (robot.launch decision:=false) and the probe node
(localisation_error:=true: /amcl_error, metres, one per AMCL pose). Navigation drives the
office floor's loop three times over, so the robot is moving for the whole measurement. Then:

    anyscale thresholds COPY_OF_testbed.yaml --connection laser:amcl:/scan \
        --probe /amcl_error --condition 'm.data < LIMIT' --value m.data --json

`--safe-speed off` (the default) measures AMCL itself at the laptop's 0.4 m/s: navigation's
safe-speed rule, which slows the robot to 0.1 m per correction and stops it after 2 s without
one, is switched off (max_dead_reckoning 100, localisation_timeout 1e6), as the paper's Table I
is "at 0.4 m/s". `--safe-speed on` measures the demo as it ships, where the rule hides a slow
AMCL by slowing the robot down.

    /usr/bin/python3 tests/bench/bench_thresholds.py
    /usr/bin/python3 tests/bench/bench_thresholds.py --safe-speed on --limit 0.25 --amcl-rate 10
"""
import argparse
import datetime
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "anyscale_core", "src"))
from anyscale_core.process_group import stop_process_group  # noqa: E402

DEMO = os.path.join(ROOT, "src", "anyscale_nav_demo")
MODEL = os.path.join(DEMO, "config", "testbed.yaml")
WORLD = os.path.join(DEMO, "maps", "office_floor_world.yaml")
ANYSCALE = os.path.join(ROOT, "src", "anyscale_core", "scripts", "anyscale")
PAPER = {"freq_min": 5, "freq_opt": 10, "tolerance": 2}     # Table I, Laser-AMCL


def log(msg):
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--safe-speed", choices=("off", "on"), default="off",
                   help="navigation's safe-speed rule (default off: the robot at 0.4 m/s)")
    p.add_argument("--limit", type=float, default=0.25,
                   help="AMCL is correct while its position error is below this, m (0.25)")
    p.add_argument("--amcl-rate", type=float, default=5.0,
                   help="AMCL's max_update_rate, Hz (the demo's 5: Table I's AMCL-EKF optimum)")
    p.add_argument("--settle", type=float, default=5.0, help="thresholds --settle (5 s)")
    p.add_argument("--step", type=float, default=20.0, help="thresholds --step (20 s)")
    p.add_argument("--outages", default="0.5,1,2,3,5,8", help="thresholds --outages")
    p.add_argument("--rates", default="", help="thresholds --rates (default: its ladder)")
    p.add_argument("--out", default=os.path.join(ROOT, "results", "bench_thresholds"),
                   help="where the model copy, the logs and thresholds.json go")
    return p.parse_args(argv)


def stop(proc):
    if proc.poll() is None:
        stop_process_group(proc, 20)


def raise_interrupt(*_):
    raise KeyboardInterrupt


def main(argv=None) -> int:
    args = parse_args(argv)
    out = os.path.join(args.out, datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
                       + f"-safe-speed-{args.safe_speed}")
    os.makedirs(out)
    model = os.path.join(out, "testbed_thresholds.yaml")
    shutil.copy(MODEL, model)
    with open(WORLD) as f:
        goals = yaml.safe_load(f)["goals"] * 3
    port = free_port()
    env = {**os.environ, "ROS_MASTER_URI": f"http://localhost:{port}",
           "ROS_HOSTNAME": "localhost", "ROS_LOG_DIR": os.path.join(out, "logs"),
           "ROS_HOME": out, "PATH": "/usr/bin:" + os.environ.get("PATH", "")}
    env.pop("ROS_IP", None)
    launch_args = ["decision:=false", "localisation_error:=true", "record:=false",
                   f"model:={model}", f"goals:={json.dumps(goals)}",
                   f"amcl_rate:={args.amcl_rate:g}"]
    if args.safe_speed == "off":
        launch_args.append("max_dead_reckoning:=100")
    signal.signal(signal.SIGTERM, raise_interrupt)
    with open(os.path.join(out, "roslaunch.log"), "w") as launch_log:
        launch = subprocess.Popen(["roslaunch", "-p", str(port), "anyscale_nav_demo",
                                   "robot.launch", *launch_args], env=env, stdout=launch_log,
                                  stderr=subprocess.STDOUT, start_new_session=True)
    try:
        time.sleep(12)       # the master, the simulator, the agent and the parameters
        if args.safe_speed == "off":
            # Navigation is started later by thresholds (through the agent): it reads this then.
            subprocess.run(["rosparam", "set", "/navigation/localisation_timeout", "1000000.0"],
                           env=env, check=True)
        command = ["/usr/bin/python3", ANYSCALE, "thresholds", model, "--connection",
                   "laser:amcl:/scan", "--probe", "/amcl_error", "--condition",
                   f"m.data < {args.limit:g}", "--value", "m.data", "--settle", str(args.settle),
                   "--step", str(args.step), "--outages", args.outages, "--json"]
        command += ["--rates", args.rates] if args.rates else []
        log("safe-speed " + args.safe_speed + ": " + " ".join(command[2:]))
        run = subprocess.run(command, env=env, stdout=subprocess.PIPE, stderr=None, text=True)
    finally:
        stop(launch)
    if run.returncode != 0:
        log(f"anyscale thresholds failed (exit {run.returncode}); logs in {out}")
        return 1
    result = json.loads(run.stdout)
    with open(os.path.join(out, "thresholds.json"), "w") as f:
        json.dump(result, f, indent=2)
    print(f"\nlaser -> AMCL, source {result['source_hz']:g} Hz, probe {result['probe']}, "
          f"safe-speed rule {args.safe_speed}, AMCL max_update_rate {args.amcl_rate:g} Hz")
    print("| step | delivered Hz | probe passed | mean error, m | correct |")
    print("|---|---|---|---|---|")
    for s in result["steps"]:
        what = f"{s['rate_hz']:g} Hz" if not s["outage_s"] else \
            f"{s['outage_s']:g} s cut at {s['rate_hz']:g} Hz"
        value = "-" if s["value_mean"] is None else f"{s['value_mean']:.3f}"
        print(f"| {what} | {s['delivered_hz']:.2f} | {s['passed']}/{s['checks']} | {value} | "
              f"{'yes' if s['correct'] else 'NO'} |")
    print("\n| | freq_min Hz | freq_opt Hz | tolerance s |")
    print("|---|---|---|---|")
    tolerance = ("not measured" if result["tolerance"] is None else
                 f"{result['tolerance']:g}"
                 + (" (or more)" if result["tolerance_is_lower_bound"] else ""))
    print(f"| anyscale thresholds | {result['freq_min']:g}"
          f"{' (or lower)' if result['freq_min_is_upper_bound'] else ''} | "
          f"{result['freq_opt']:g} | {tolerance} |")
    print(f"| paper, Table I | {PAPER['freq_min']} | {PAPER['freq_opt']} | "
          f"{PAPER['tolerance']} |")
    if result["tolerance"] is None:
        print(f"\ntolerance not measured: {result['tolerance_unmeasured']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
