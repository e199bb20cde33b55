#!/usr/bin/python3
"""Benchmark of the agent's link statistics against a link whose rate we set: two network
namespaces joined by a veth pair, roscore and the master scale's agent in one, a remote
agent in the other, `tc tbf` on the remote's egress (the direction the bulk probes take).
Prints the estimate (every status sample, median and range) next to the configured rate;
asserts nothing. Needs root and the
workspace built and sourced.
Usage: /usr/bin/python3 tests/bench/bench_agent_link.py [--rates 50 20 5] [--seconds 20]
"""
import argparse
import ast
import os
import shutil
import signal
import statistics
import subprocess
import sys
import time

from anyscale_testbed.two_scale_testbed import (TwoScaleTestbed, missing_capabilities,
                                                namespace_exec, process_layout)

PID = os.getpid()
LAYOUT = process_layout("asbl", "10.213.78", PID)
URI = "http://%s:11311" % LAYOUT.robot.address
MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src", "anyscale_agent_cpp", "test",
                     "config", "test_model.yaml")

STATUS_READER = r"""
import math, sys, time, rospy
from anyscale_msgs.msg import ScaleStatus
rospy.init_node('bench_link_reader', anonymous=True)
seconds = float(sys.argv[1]); bw = []; rtt = []; up = []
def cb(m):
    if m.scale != 'laptop': return
    up.append(m.link.up)
    if not math.isnan(m.link.bandwidth_mbps): bw.append((time.time(), m.link.bandwidth_mbps))
    if not math.isnan(m.link.rtt_mean_s): rtt.append(m.link.rtt_mean_s)
rospy.Subscriber('/anyscale/status', ScaleStatus, cb)
time.sleep(seconds)
print(repr((bw, rtt, up)))
"""


def ros_env(end):
    env = dict(os.environ, ROS_MASTER_URI=URI, ROS_IP=end.address, ROS_HOME="/tmp/%s_home" % end.namespace)
    env.pop("ROS_HOSTNAME", None)
    return env


def read_status(seconds):
    """Starts the status reader in the master's namespace; returns the process."""
    return subprocess.Popen(namespace_exec(LAYOUT.robot, ["/usr/bin/python3", "-c", STATUS_READER, str(seconds)]),
                            env=ros_env(LAYOUT.robot), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True)


def start_remote_agent(bed, agent, *extra):
    return bed.start("laptop", [agent, "__name:=anyscale_agent_laptop", "_scale:=laptop", "_master_scale:=robot",
                                "_model:=" + MODEL] + list(extra), env=ros_env(LAYOUT.laptop))


def stop(proc):
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=20)


def step_down(bed, agent, burst_kbit):
    """How long the estimate takes to follow the link from 50 down to 5 Mbit/s."""
    bed.shape(50, burst_kbit)
    remote = start_remote_agent(bed, agent)  # default bulk period, 5 s
    time.sleep(12.0)
    reader = read_status(25)
    time.sleep(5.0)
    t_step = time.time()
    bed.shape(5, burst_kbit)
    out, _ = reader.communicate(timeout=90)
    bw, _, _ = ast.literal_eval(out.strip().splitlines()[-1])
    before = [b for t, b in bw if t < t_step]
    after = [t - t_step for t, b in bw if t >= t_step and b < 10.0]
    print("step 50 -> 5 Mbit/s with the default 5 s bulk period: estimate %.1f Mbit/s before, below 10 Mbit/s"
          " %s after the step (final %.1f)" % (before[-1] if before else float("nan"),
                                               "%.1f s" % after[0] if after else "never", bw[-1][1]))
    stop(remote)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[50.0, 20.0, 5.0], help="tbf rates [Mbit/s]")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--burst", default="32kbit", help="tbf burst (kbit)")
    args = parser.parse_args()
    missing = missing_capabilities(need_cgroups=False)
    if missing:
        sys.exit("the link bench needs " + "; ".join(missing))
    from catkin.find_in_workspaces import find_in_workspaces
    agent = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                               first_matching_workspace_only=True)
    if not agent:
        sys.exit("anyscale_agent not built / workspace not sourced")
    burst_kbit = int(args.burst.rstrip("kbit"))
    # The shared test bed builds the namespaces and veth pair and removes them, processes
    # included, however the run ends. tbf shapes both directions; the bulk probes go
    # remote -> master and the answers are empty.
    with TwoScaleTestbed(LAYOUT, cgroup_prefix="asbl%d" % PID) as bed:
        bed.start("robot", ["roscore"], env=ros_env(LAYOUT.robot))
        check = ["/usr/bin/python3", "-c", "import rosgraph, sys; sys.exit(not rosgraph.is_master_online())"]
        while subprocess.run(namespace_exec(LAYOUT.robot, check), env=ros_env(LAYOUT.robot)).returncode != 0:
            time.sleep(0.3)
        bed.start("robot", [agent[0], "__name:=anyscale_agent_robot", "_scale:=robot", "_is_master:=true",
                            "_model:=" + MODEL], env=ros_env(LAYOUT.robot))
        print("link estimate of a fresh remote agent per rate (bulk probe 64 KiB every 2 s; %.0f s per rate)"
              % args.seconds)
        print("  %-16s %-28s %-12s %s" % ("tbf rate", "estimate median [min, max]", "RTT mean", "up"))
        for rate in [None] + args.rates:
            if rate is None:
                label = "none (veth)"
            else:
                bed.shape(rate, burst_kbit)
                label = "%g Mbit/s" % rate
            # A fresh remote agent per rate: the smoothed estimate must not carry the last rate over.
            remote = start_remote_agent(bed, agent[0], "_link_bulk_period_s:=2.0")
            time.sleep(3.0)
            out, _ = read_status(args.seconds).communicate(timeout=args.seconds + 60)
            bw, rtt, up = ast.literal_eval(out.strip().splitlines()[-1])
            bw = [b for _, b in bw]
            est = "%.1f [%.1f, %.1f]" % (statistics.median(bw), min(bw), max(bw)) if bw else "n/a"
            r = "%.2f ms" % (1e3 * statistics.mean(rtt)) if rtt else "n/a"
            print("  %-16s %-28s %-12s %.0f %%" % (label, est, r, 100.0 * sum(up) / max(1, len(up))))
            stop(remote)
        step_down(bed, agent[0], burst_kbit)
    for end in LAYOUT.ends:
        shutil.rmtree("/tmp/%s_home" % end.namespace, ignore_errors=True)


if __name__ == "__main__":
    main()
