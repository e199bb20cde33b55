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
import statistics
import subprocess
import sys
import time

PID = os.getpid()
NS_M, NS_R = "asbl%d_m" % PID, "asbl%d_r" % PID
VETH_M, VETH_R = "abm%d" % PID, "abr%d" % PID
IP_M, IP_R = "10.213.78.1", "10.213.78.2"
URI = "http://%s:11311" % IP_M
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


def sh(*args):
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def in_ns(ns, ip, argv, **kw):
    env = dict(os.environ, ROS_MASTER_URI=URI, ROS_IP=ip, ROS_HOME="/tmp/%s_home" % ns)
    env.pop("ROS_HOSTNAME", None)
    return subprocess.Popen(["ip", "netns", "exec", ns] + argv, env=env, **kw)


def tbf(rate_mbit, burst="32kbit"):
    sh("ip", "netns", "exec", NS_R, "tc", "qdisc", "replace", "dev", VETH_R, "root", "tbf", "rate",
       "%gmbit" % rate_mbit, "burst", burst, "latency", "50ms")


def step_down(agent, procs, quiet):
    """How long the estimate takes to follow the link from 50 down to 5 Mbit/s."""
    tbf(50)
    remote = in_ns(NS_R, IP_R, [agent, "__name:=anyscale_agent_laptop", "_scale:=laptop", "_master_scale:=robot",
                                "_model:=" + MODEL], **quiet)  # default bulk period, 5 s
    procs.append(remote)
    time.sleep(12.0)
    reader = in_ns(NS_M, IP_M, ["/usr/bin/python3", "-c", STATUS_READER, "25"], stdout=subprocess.PIPE,
                   stderr=subprocess.DEVNULL, text=True)
    time.sleep(5.0)
    t_step = time.time()
    tbf(5)
    out, _ = reader.communicate(timeout=90)
    bw, _, _ = ast.literal_eval(out.strip().splitlines()[-1])
    before = [b for t, b in bw if t < t_step]
    after = [t - t_step for t, b in bw if t >= t_step and b < 10.0]
    print("step 50 -> 5 Mbit/s with the default 5 s bulk period: estimate %.1f Mbit/s before, below 10 Mbit/s"
          " %s after the step (final %.1f)" % (before[-1] if before else float("nan"),
                                               "%.1f s" % after[0] if after else "never", bw[-1][1]))
    remote.send_signal(2)
    remote.wait(timeout=20)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[50.0, 20.0, 5.0], help="tbf rates [Mbit/s]")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--burst", default="32kbit", help="tbf burst")
    args = parser.parse_args()
    if os.geteuid() != 0:
        sys.exit("needs root (ip netns, tc)")
    from catkin.find_in_workspaces import find_in_workspaces
    agent = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                               first_matching_workspace_only=True)
    if not agent:
        sys.exit("anyscale_agent not built / workspace not sourced")
    procs = []
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        sh("ip", "netns", "add", NS_M)
        sh("ip", "netns", "add", NS_R)
        sh("ip", "link", "add", VETH_M, "type", "veth", "peer", "name", VETH_R)
        sh("ip", "link", "set", VETH_M, "netns", NS_M)
        sh("ip", "link", "set", VETH_R, "netns", NS_R)
        for ns, dev, ip in ((NS_M, VETH_M, IP_M), (NS_R, VETH_R, IP_R)):
            sh("ip", "-n", ns, "addr", "add", ip + "/24", "dev", dev)
            sh("ip", "-n", ns, "link", "set", dev, "up")
            sh("ip", "-n", ns, "link", "set", "lo", "up")
        procs.append(in_ns(NS_M, IP_M, ["roscore"], **quiet))
        check = ["/usr/bin/python3", "-c", "import rosgraph, sys; sys.exit(not rosgraph.is_master_online())"]
        while in_ns(NS_M, IP_M, check).wait() != 0:
            time.sleep(0.3)
        procs.append(in_ns(NS_M, IP_M, [agent[0], "__name:=anyscale_agent_robot", "_scale:=robot", "_is_master:=true",
                                        "_model:=" + MODEL], **quiet))
        print("link estimate of a fresh remote agent per rate (bulk probe 64 KiB every 2 s; %.0f s per rate)"
              % args.seconds)
        print("  %-16s %-28s %-12s %s" % ("tbf rate", "estimate median [min, max]", "RTT mean", "up"))
        for rate in [None] + args.rates:
            if rate is None:
                label = "none (veth)"
            else:
                tbf(rate, args.burst)
                label = "%g Mbit/s" % rate
            # A fresh remote agent per rate: the smoothed estimate must not carry the last rate over.
            remote = in_ns(NS_R, IP_R, [agent[0], "__name:=anyscale_agent_laptop", "_scale:=laptop",
                                        "_master_scale:=robot", "_model:=" + MODEL, "_link_bulk_period_s:=2.0"],
                           **quiet)
            procs.append(remote)
            time.sleep(3.0)
            reader = in_ns(NS_M, IP_M, ["/usr/bin/python3", "-c", STATUS_READER, str(args.seconds)],
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
            out, _ = reader.communicate(timeout=args.seconds + 60)
            bw, rtt, up = ast.literal_eval(out.strip().splitlines()[-1])
            bw = [b for _, b in bw]
            
            est = "%.1f [%.1f, %.1f]" % (statistics.median(bw), min(bw), max(bw)) if bw else "n/a"
            r = "%.2f ms" % (1e3 * statistics.mean(rtt)) if rtt else "n/a"
            print("  %-16s %-28s %-12s %.0f %%" % (label, est, r, 100.0 * sum(up) / max(1, len(up))))
            remote.send_signal(2)
            remote.wait(timeout=20)
        step_down(agent[0], procs, quiet)
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.send_signal(2)
                try:
                    p.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    p.kill()
        subprocess.run(["ip", "netns", "del", NS_M], stderr=subprocess.DEVNULL)
        subprocess.run(["ip", "netns", "del", NS_R], stderr=subprocess.DEVNULL)
        for ns in (NS_M, NS_R):
            shutil.rmtree("/tmp/%s_home" % ns, ignore_errors=True)


if __name__ == "__main__":
    main()
