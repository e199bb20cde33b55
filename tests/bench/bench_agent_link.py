#!/usr/bin/python3
"""Benchmark of the agent's link bandwidth estimate against a link of known rate, ICMP echo vs
ROS probes.

Two network namespaces joined by a veth pair (`tc tbf` on both ends), roscore and the master
scale's agent in one, a fresh remote agent per case in the other. Each case runs once with the
agent's default bulk probe (ICMP echo, answered by the master's kernel) and once with
`_link_bandwidth_by_icmp:=false` (ROS probes echoed by the master's agent), in two conditions:

  idle  the master's roscore and agent alone (their cgroup has no quota);
  busy  the same processes in a cgroup v1 CPU group held at the test bed robot's quota
        (0.37 cores) and saturated by busy loops at nice 5, like a robot running its nodes.

Then a step: the link falls from 27 to 3 Mbit/s while a UDP stream of 6 Mbit/s flows from the
master's namespace to the remote; it reports how long each method takes to read below 8 Mbit/s.
Prints a table (estimate median [min, max] and estimate/rate) and the step times; asserts
nothing. Needs root, a writable /sys/fs/cgroup/cpu, and the workspace built and sourced.
Everything it creates (namespaces asbl<PID>_m/_r, cgroup /sys/fs/cgroup/cpu/asbl<PID>_robot,
processes, /tmp/asbl<PID>_* files) is removed at the end, also after an error, Ctrl-C or SIGTERM.

Usage: /usr/bin/python3 tests/bench/bench_agent_link.py [--rates 27 6] [--seconds 8]
       [--conditions idle busy] [--step-in idle busy] [--step-seconds 12]
"""
import argparse
import ast
import dataclasses
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import time

try:
    from anyscale_testbed.two_scale_testbed import (CFS_PERIOD_US, TwoScaleLayout, TwoScaleTestbed,
                                                    missing_capabilities, namespace_exec,
                                                    process_layout)
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

PID = os.getpid()
_BASE = process_layout("asbl", "10.213.78", PID)
DEFAULT_QUOTA_CORES = 0.37
# The master's end carries a CPU group (the test bed creates and removes it); its quota is set
# per condition: none when idle, the robot's when busy.
LAYOUT = TwoScaleLayout(robot=dataclasses.replace(_BASE.robot, cpu_cores=DEFAULT_QUOTA_CORES),
                        laptop=_BASE.laptop)
CGROUP_PREFIX = "asbl%d" % PID
URI = "http://%s:11311" % LAYOUT.robot.address
TMP = "/tmp/asbl%d" % PID
MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src",
                     "anyscale_agent_cpp", "test", "config", "test_model.yaml")
# Both set explicitly: a private parameter given on the command line stays on the parameter
# server after the agent ends, and the next agent of the same name would inherit it.
METHODS = (("ICMP", ["_link_bandwidth_by_icmp:=true"]), ("ROS", ["_link_bandwidth_by_icmp:=false"]))
STREAM_PORT = 47000

STATUS_READER = r"""
import math, sys, time, rospy
from anyscale_msgs.msg import ScaleStatus
rospy.init_node('bench_link_reader', anonymous=True)
seconds = float(sys.argv[1]); samples = []
def cb(m):
    if m.scale != 'laptop': return
    samples.append((time.time(), bool(m.link.up), float(m.link.bandwidth_mbps),
                    float(m.link.rtt_mean_s)))
rospy.Subscriber('/anyscale/status', ScaleStatus, cb)
time.sleep(seconds)
print(repr(samples).replace('nan', 'None'))
"""

# Paced UDP sender: datagrams of 1250 bytes, topped up every 2 ms to the byte count the rate allows.
STREAM_SENDER = r"""
import socket, sys, time
dest, port, mbps = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
payload = b'x' * 1250; sent = 0; t0 = time.monotonic()
while True:
    due = (time.monotonic() - t0) * mbps * 1e6 / 8.0
    while sent + len(payload) <= due:
        try: s.sendto(payload, (dest, port))
        except OSError: pass
        sent += len(payload)
    time.sleep(0.002)
"""

STREAM_SINK = r"""
import socket, sys
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind((sys.argv[1], int(sys.argv[2])))
while True: s.recv(65536)
"""

HOG = "while True: pass"


def log(text):
    print(text, file=sys.stderr, flush=True)


def ros_env(end):
    env = dict(os.environ, ROS_MASTER_URI=URI, ROS_IP=end.address,
               ROS_HOME="%s_home_%s" % (TMP, end.scale))
    env.pop("ROS_HOSTNAME", None)
    return env


def write_cgroup(bed, name, value):
    with open(os.path.join(bed.quotas["robot"].path, name), "w") as f:
        f.write(str(value))


def cpu_stat(bed):
    with open(os.path.join(bed.quotas["robot"].path, "cpu.stat")) as f:
        return {k: int(v) for k, v in (line.split() for line in f if line.strip())}


def read_status(bed, seconds):
    """Starts the status reader in the master's namespace (outside the CPU group); returns it."""
    reader = ["/usr/bin/python3", "-c", STATUS_READER, str(seconds)]
    proc = subprocess.Popen(namespace_exec(LAYOUT.robot, reader), env=ros_env(LAYOUT.robot),
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            start_new_session=True)
    bed.processes.append(proc)  # ended by the teardown if the run is cut short
    return proc


def collect(proc, seconds):
    out, _ = proc.communicate(timeout=seconds + 60)
    return ast.literal_eval(out.strip().splitlines()[-1])


def start_remote_agent(bed, agent, method_args, log_path):
    return bed.start("laptop", [agent, "__name:=anyscale_agent_laptop", "_scale:=laptop",
                                "_master_scale:=robot", "_model:=" + MODEL] + list(method_args),
                     env=ros_env(LAYOUT.laptop), log_path=log_path)


def bandwidth_method(log_path):
    """The agent's own line on how it measures the bandwidth (ICMP, or the ROS fallback and why)."""
    try:
        with open(log_path, errors="replace") as f:
            for line in f:
                if "link bandwidth by" in line:
                    said = line.split("link bandwidth by", 1)[1]
                    return re.sub(r"\x1b\[[0-9;]*m", "", said).strip()  # without colour codes
    except OSError:
        pass
    return "?"


def signal_group(proc, sig):
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


def stop(bed, proc):
    signal_group(proc, signal.SIGINT)
    try:
        proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        signal_group(proc, signal.SIGKILL)
        proc.wait(timeout=5)
    if proc in bed.processes:
        bed.processes.remove(proc)


def fmt_range(values, scale=1.0, spec="%.1f"):
    if not values:
        return "n/a"
    shown = (statistics.median(values) / scale, min(values) / scale, max(values) / scale)
    return (spec + " [" + spec + ", " + spec + "]") % shown


def fmt_or(spec, value, missing="n/a"):
    return missing if value is None else spec % value


def method_label(log_path, exited):
    """The bulk probe the agent logged, and its exit status if it ended during the case."""
    return bandwidth_method(log_path) + ("" if exited is None
                                         else " (agent EXITED, status %d)" % exited)


def static_case(bed, agent, method_args, rate, seconds, log_path):
    remote = start_remote_agent(bed, agent, method_args, log_path)
    time.sleep(3.0)
    samples = collect(read_status(bed, seconds), seconds)
    exited = remote.poll()
    stop(bed, remote)
    bw = [b for _, _, b, _ in samples if b is not None]
    rtt = [r for _, _, _, r in samples if r is not None]
    up = [u for _, u, _, _ in samples]
    return dict(bw=bw, rtt=rtt, up=100.0 * sum(up) / max(1, len(up)), n=len(samples),
                method=method_label(log_path, exited))


def step_case(bed, agent, method_args, args, log_path):
    """27 Mbit/s with a 6 Mbit/s UDP stream master -> remote; then the link falls to 3 Mbit/s."""
    burst = args.burst_kbit
    bed.shape(args.step_from, burst)
    sink = bed.start("laptop", ["/usr/bin/python3", "-c", STREAM_SINK, LAYOUT.laptop.address,
                                str(STREAM_PORT)], cpu_quota=False)
    # Outside the master's CPU group: the stream's rate is the case's input, not something to
    # measure.
    sender = bed.start("robot", ["/usr/bin/python3", "-c", STREAM_SENDER, LAYOUT.laptop.address,
                                 str(STREAM_PORT), str(args.stream_mbps)], cpu_quota=False)
    remote = start_remote_agent(bed, agent, method_args, log_path)
    time.sleep(args.step_settle)
    pre = 5.0
    reader = read_status(bed, pre + args.step_seconds)
    time.sleep(pre)
    bed.shape(args.step_to, burst)
    t_step = time.time()
    samples = collect(reader, pre + args.step_seconds)
    exited = remote.poll()
    for proc in (remote, sender, sink):
        stop(bed, proc)
    before = [b for t, _, b, _ in samples if t < t_step and b is not None]
    after = [(t - t_step, u, b) for t, u, b, _ in samples if t >= t_step]
    below = [dt for dt, _, b in after if b is not None and b < args.step_threshold]
    known = [b for _, _, b in after if b is not None]
    timeline, last = [], before[-1] if before else None
    for dt, _, b in after:
        if b != last:
            timeline.append("%+.1f s %s" % (dt, "n/a" if b is None else "%.1f" % b))
            last = b
    return dict(before=before[-1] if before else None, detect=below[0] if below else None,
                timeline=timeline, final=known[-1] if known else None, after=known,
                nan=sum(1 for _, _, b in after if b is None), n_after=len(after),
                method=method_label(log_path, exited))


def report(args, rows, steps, throttling):
    print("link bandwidth estimate of a fresh remote agent per case: bulk probe %s (agent "
          "defaults: 32 KiB every 2 s); tbf burst %s latency 50ms on both ends; %.0f s sampled "
          "per case at 2 Hz" % ("ICMP echo vs ROS probes", args.burst, args.seconds))
    print("idle: master's roscore + agent alone; busy: the same in a cgroup at %.2f cores "
          "(cfs_quota_us %d / %d) with %d busy loops at nice 5"
          % (args.quota_cores, int(args.quota_cores * CFS_PERIOD_US), CFS_PERIOD_US, args.hogs))
    if throttling:
        print("busy group during the busy cases: throttled in %d of %d CFS periods"
              % (throttling.get("nr_throttled", 0), throttling.get("nr_periods", 0)))
    if rows:
        print("  %-10s %-10s %-7s %-26s %-20s %-8s %-10s %s"
              % ("condition", "rate", "method", "estimate median [min, max]", "estimate/rate",
                 "samples", "RTT mean", "up"))
    for r in rows:
        print("  %-10s %-10s %-7s %-26s %-20s %-8s %-10s %.0f %%"
              % (r["condition"], "%g Mbit/s" % r["rate"], r["name"], fmt_range(r["bw"]),
                 fmt_range(r["bw"], r["rate"], "%.2f"), "%d/%d" % (len(r["bw"]), r["n"]),
                 "%.2f ms" % (1e3 * statistics.mean(r["rtt"])) if r["rtt"] else "n/a", r["up"]))
    if steps:
        print("step %g -> %g Mbit/s with a %g Mbit/s UDP stream master -> remote: time until the "
              "estimate reads below %g Mbit/s"
              % (args.step_from, args.step_to, args.stream_mbps, args.step_threshold))
        print("  %-10s %-7s %-8s %-10s %-30s %-7s %s"
              % ("condition", "method", "before", "below %g" % args.step_threshold,
                 "after the step: median [min, max]", "final", "no estimate"))
        for s in steps:
            print("  %-10s %-7s %-8s %-10s %-30s %-7s %d of %d samples"
                  % (s["condition"], s["name"], fmt_or("%.1f", s["before"]),
                     fmt_or("%.1f s", s["detect"], "never"), fmt_range(s["after"]),
                     fmt_or("%.1f", s["final"]), s["nan"], s["n_after"]))
        print("  estimate after the step, at each change [s after the step, Mbit/s]:")
        for s in steps:
            print("  %-10s %-7s %s"
                  % (s["condition"], s["name"], ", ".join(s["timeline"]) or "no change"))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     epilog=__doc__.split("\n\n", 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rates", type=float, nargs="+", default=[27.0, 6.0],
                        help="tbf rates [Mbit/s] (27 6)")
    parser.add_argument("--seconds", type=float, default=8.0,
                        help="status sampled per case [s] (8)")
    parser.add_argument("--conditions", nargs="+", choices=["idle", "busy"],
                        default=["idle", "busy"])
    parser.add_argument("--step-in", nargs="*", choices=["idle", "busy"], default=["idle", "busy"],
                        help="conditions in which to run the step case (none: no step)")
    parser.add_argument("--step-from", type=float, default=27.0, help="[Mbit/s] (27)")
    parser.add_argument("--step-to", type=float, default=3.0, help="[Mbit/s] (3)")
    parser.add_argument("--stream-mbps", type=float, default=6.0,
                        help="UDP stream master -> remote (6)")
    parser.add_argument("--step-repeat", type=int, default=1,
                        help="step cases per method and condition (1)")
    parser.add_argument("--step-threshold", type=float, default=8.0,
                        help="'detected' below this [Mbit/s] (8)")
    parser.add_argument("--step-settle", type=float, default=6.0,
                        help="agent run-in before the reader [s] (6)")
    parser.add_argument("--step-seconds", type=float, default=12.0,
                        help="observed after the step [s] (12)")
    parser.add_argument("--quota-cores", type=float, default=DEFAULT_QUOTA_CORES,
                        help="busy: CPU quota of the master's group [cores] (0.37)")
    parser.add_argument("--hogs", type=int, default=3,
                        help="busy: busy loops at nice 5 in the group (3)")
    parser.add_argument("--burst", default="32kbit", help="tbf burst (32kbit)")
    args = parser.parse_args()
    args.burst_kbit = int(args.burst.rstrip("kbit"))
    conditions = [c for c in ("idle", "busy") if c in set(args.conditions) | set(args.step_in)]

    missing = missing_capabilities(need_cgroups=True)
    if missing:
        sys.exit("the link bench needs " + "; ".join(missing))
    from catkin.find_in_workspaces import find_in_workspaces
    agent = find_in_workspaces(["libexec"], project="anyscale_agent_cpp", path="anyscale_agent",
                               first_matching_workspace_only=True)
    if not agent:
        sys.exit("anyscale_agent not built / workspace not sourced")
    agent = agent[0]
    built = os.path.getmtime(agent)

    def on_term(*_):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, on_term)
    signal.signal(signal.SIGINT, signal.default_int_handler)

    static_in = [c for c in conditions if c in args.conditions]
    step_in = [c for c in conditions if c in args.step_in]
    n_cases = (len(args.rates) * len(METHODS) * len(static_in)
               + len(METHODS) * args.step_repeat * len(step_in))
    case = 0
    rows, steps, throttling = [], [], {}
    t0 = time.time()
    try:
        # The test bed builds the namespaces, veth pair and CPU group, and removes them, processes
        # included, however the run ends.
        with TwoScaleTestbed(LAYOUT, cgroup_prefix=CGROUP_PREFIX) as bed:
            write_cgroup(bed, "cpu.cfs_quota_us", -1)  # idle: no quota
            bed.start("robot", ["roscore"], env=ros_env(LAYOUT.robot))
            check = namespace_exec(LAYOUT.robot, [
                "/usr/bin/python3", "-c",
                "import rosgraph, sys; sys.exit(not rosgraph.is_master_online())"])
            while subprocess.run(check, env=ros_env(LAYOUT.robot)).returncode != 0:
                time.sleep(0.3)
            bed.start("robot", [agent, "__name:=anyscale_agent_robot", "_scale:=robot",
                                "_is_master:=true", "_model:=" + MODEL], env=ros_env(LAYOUT.robot))
            for condition in conditions:
                if condition == "busy":
                    write_cgroup(bed, "cpu.cfs_period_us", CFS_PERIOD_US)
                    write_cgroup(bed, "cpu.cfs_quota_us", int(args.quota_cores * CFS_PERIOD_US))
                    for _ in range(args.hogs):
                        bed.start("robot", ["nice", "-n", "5", "/usr/bin/python3", "-c", HOG])
                    time.sleep(1.0)
                    stat0 = cpu_stat(bed)
                for rate in (args.rates if condition in args.conditions else []):
                    bed.shape(rate, args.burst_kbit)
                    for method, method_args in METHODS:
                        case += 1
                        log("[%d/%d %3.0f s] %s master, tbf %g Mbit/s, %s ..."
                            % (case, n_cases, time.time() - t0, condition, rate, method))
                        r = static_case(bed, agent, method_args, rate, args.seconds,
                                        "%s_%s_%g_%s.log" % (TMP, condition, rate, method))
                        r.update(condition=condition, rate=rate, name=method)
                        rows.append(r)
                        log("    %s; estimate %s Mbit/s (%d samples, up %.0f %%)"
                            % (r["method"], fmt_range(r["bw"]), r["n"], r["up"]))
                if condition in args.step_in:
                    for method, method_args in METHODS * args.step_repeat:
                        case += 1
                        log("[%d/%d %3.0f s] %s master, step %g -> %g Mbit/s with a %g Mbit/s "
                            "stream, %s ..."
                            % (case, n_cases, time.time() - t0, condition, args.step_from,
                               args.step_to, args.stream_mbps, method))
                        r = step_case(bed, agent, method_args, args,
                                      "%s_%s_step_%s_%d.log" % (TMP, condition, method, case))
                        r.update(condition=condition, name=method)
                        steps.append(r)
                        log("    %s; below %g Mbit/s after %s"
                            % (r["method"], args.step_threshold,
                               fmt_or("%.1f s", r["detect"], "never")))
                if condition == "busy":
                    stat1 = cpu_stat(bed)
                    throttling = {k: stat1[k] - stat0.get(k, 0) for k in stat1}
    except KeyboardInterrupt:
        log("interrupted; the test bed was removed")
        return 130
    finally:
        for path in os.listdir("/tmp"):
            if path.startswith(os.path.basename(TMP) + "_"):
                full = os.path.join("/tmp", path)
                if os.path.isdir(full):
                    shutil.rmtree(full, ignore_errors=True)
                else:
                    os.remove(full)

    if os.path.getmtime(agent) != built:
        print("WARNING: %s was rebuilt during the run; cases before and after used different "
              "builds" % agent)
    print("agent %s, built %s"
          % (agent, time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(built))))
    report(args, rows, steps, throttling)
    return 0


if __name__ == "__main__":
    sys.exit(main())
