#!/usr/bin/python3
"""Benchmark (prints, asserts nothing): CPU of every node of the navigation demo while the
robot drives the office floor, each at its optimal rate, and the whole pipeline's share of
this machine, with the measured rates of Table I's connections, side by side in one run.

Starts its own master on a private port (default 11533) and stops it afterwards.
    /usr/bin/python3 tests/bench/bench_nav_pipeline.py [--seconds 30] [--port 11533] \\
        [--world office_floor]
"""
import argparse
import os
import signal
import subprocess
import sys
import time
import xmlrpc.client

import psutil

NODES = ["world_sim", "laser", "odometer", "camera", "base_driver", "user", "map_server",
         "odometry", "amcl", "ekf", "navigation", "ar_recognition"]
TOPICS = ["/scan", "/joint_states", "/camera/image_raw", "/odom", "/amcl_pose",
          "/odometry/filtered", "/ar_markers", "/cmd_vel"]


def node_pid(master, name):
    code, _, uri = master.lookupNode("/bench", "/" + name)
    if code != 1:
        return None
    code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/bench")
    return pid if code == 1 else None


def measure_rates(seconds):
    """Rates of Table I's topics with one rospy subscriber per topic (AnyMsg: no decoding)."""
    import rospy
    rospy.init_node("bench_rates", anonymous=True, disable_signals=True)
    counts = {t: [] for t in TOPICS}
    subs = [rospy.Subscriber(t, rospy.AnyMsg, lambda _m, t=t: counts[t].append(time.time()))
            for t in TOPICS]
    time.sleep(seconds)
    for s in subs:
        s.unregister()
    return {t: (len(v) - 1) / (v[-1] - v[0]) if len(v) > 2 else 0.0 for t, v in counts.items()}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--warmup", type=float, default=15.0)
    ap.add_argument("--port", type=int, default=11533)
    ap.add_argument("--world", default="office_floor")
    ap.add_argument("--amcl-rate", default="5.0",
                    help="AMCL's update rate cap (robot.launch amcl_rate)")
    ap.add_argument("--attach", action="store_true",
                    help="measure the demo already running under $ROS_MASTER_URI instead")
    args = ap.parse_args()
    if args.attach:
        env = dict(os.environ)
        launch = None
    else:
        env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % args.port)
        os.environ["ROS_MASTER_URI"] = env["ROS_MASTER_URI"]
        launch = subprocess.Popen(["roslaunch", "-p", str(args.port), "anyscale_nav_demo",
                                   "robot.launch", "anyscale:=false", "world:=" + args.world,
                                   "record:=false", "amcl_rate:=" + args.amcl_rate],
                                  env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  start_new_session=True)
    try:
        time.sleep(args.warmup if launch else 0.0)
        master = xmlrpc.client.ServerProxy(env["ROS_MASTER_URI"])
        procs = {}
        for n in NODES:
            pid = node_pid(master, n)
            if pid:
                procs[n] = psutil.Process(pid)
                procs[n].cpu_percent(None)
        box = psutil.cpu_percent(None)
        t0 = time.time()
        rates = measure_rates(args.seconds)
        elapsed = time.time() - t0
        box = psutil.cpu_percent(None)
        cpu = {n: p.cpu_percent(None) for n, p in procs.items()}
        rss = {n: p.memory_info().rss / 2.0 ** 20 for n, p in procs.items()}
    finally:
        if launch is not None:
            os.killpg(launch.pid, signal.SIGINT)
            try:
                launch.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(launch.pid, signal.SIGKILL)
    cores = psutil.cpu_count()
    where = (" (attached)" if args.attach
             else " on %s, AMCL cap %s Hz" % (args.world, args.amcl_rate))
    print("Navigation demo%s, %d cores, %.0f s of driving%s"
          % (where, cores, elapsed, "" if args.attach else " after %.0f s warm-up" % args.warmup))
    print("%-16s %12s %14s %8s" % ("node", "% of a core", "% of machine", "RSS MB"))
    app = 0.0
    for n in NODES:
        c = cpu.get(n, float("nan"))
        note = "   (simulator: not an app node)" if n == "world_sim" else ""
        print("%-16s %12.1f %14.1f %8.0f%s" % (n, c, c / cores, rss.get(n, float("nan")), note))
        app += c if n != "world_sim" and c == c else 0.0
    sim = cpu.get("world_sim", 0.0)
    print("%-16s %12.1f %14.1f" % ("application", app, app / cores))
    print("%-16s %12.1f %14.1f" % ("app + simulator", app + sim, (app + sim) / cores))
    print("whole machine (all processes): %.1f %% of %d cores; headroom %.1f cores"
          % (box, cores, cores * (1 - box / 100.0)))
    print("\nmeasured rates (Hz):")
    for t in TOPICS:
        print("  %-22s %6.2f" % (t, rates[t]))


if __name__ == "__main__":
    sys.exit(main())
