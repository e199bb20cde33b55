#!/usr/bin/python3
"""Benchmark (prints, asserts nothing; needs root for cgroups): calibrates the CPU heterogeneity
of the two-scale test bed. Runs the navigation demo with the robot's node set inside a cgroup v1
CPU quota (anyscale_testbed.two_scale_testbed.CpuQuota) and measures, for each quota, the rates of
Table I's connections and every node's CPU; then the laptop case: AMCL and AR alone in a second
cgroup (on the same master), the rest of the robot in the robot's group.

The simulator (world_sim: the world, not the robot's computer) always runs outside any quota.
Node cost parameters (AMCL particles/beams, AR detector parameters) come from
src/anyscale_nav_demo/config/testbed_calibration.yaml unless given on the command line.

Each step starts a fresh demo (the robot at start A, navigation driving the loop by itself) with
the group unlimited, waits --warmup s (rospy nodes need seconds of CPU to start; under the
quota that alone would take half a minute), then applies the quota, lets it settle --settle s
and measures --duration s. While it measures, this process times the host-speed workload
(anyscale_testbed/host_speed.py) every 5 s: its median CPU ms is printed beside the rates, so a
calibration states the host speed it was made at (testbed_calibration.yaml's reference_cpu_ms;
this shared VM's speed drifts, and a quota is a share of it). The lines and tables it prints are
anyscale_testbed/cpu_calibration_report.py.

    sudo /usr/bin/python3 tests/bench/bench_cpu_calibration.py
    sudo /usr/bin/python3 tests/bench/bench_cpu_calibration.py --quotas 0.3,0.35,none \\
        --laptop-quotas 0.8
    sudo /usr/bin/python3 tests/bench/bench_cpu_calibration.py --amcl-particles 3000 \\
        --amcl-beams 120 \\
        --ar-detector-params '{"adaptiveThreshWinSizeMax": 63, "adaptiveThreshWinSizeStep": 2}'
"""
import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import xmlrpc.client

import psutil
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "src", "anyscale_testbed", "src"))
from anyscale_testbed.cpu_calibration_report import (LAPTOP_NODES, ROBOT_NODES, SIM,  # noqa: E402
                                                     TOPICS, print_report, qname, step_line)
from anyscale_testbed.host_speed import HostSpeedMonitor  # noqa: E402
from anyscale_testbed.two_scale_testbed import CpuQuota, cgroup_available  # noqa: E402

PKG = os.path.join(ROOT, "src", "anyscale_nav_demo")
CALIBRATION = os.path.join(PKG, "config", "testbed_calibration.yaml")
START = {"x": 7.4, "y": 5.9, "yaw": 0.0}     # robot.launch's defaults (office floor, start A)

RATE_COUNTER = r"""
import json, sys, time, rospy
topics, seconds = sys.argv[1].split(","), float(sys.argv[2])
rospy.init_node("cal_rates", anonymous=True, disable_signals=True)
stamps = {t: [] for t in topics}
subs = [rospy.Subscriber(t, rospy.AnyMsg, lambda _m, t=t: stamps[t].append(time.time()))
        for t in topics]
time.sleep(seconds)
for s in subs:
    s.unregister()
print(json.dumps({t: len(v) / seconds for t, v in stamps.items()}))
"""


def log(msg):
    print("[%s] %s" % (time.strftime("%H:%M:%S"), msg), flush=True)


def parse_quotas(text):
    out = []
    for q in text.split(","):
        q = q.strip().lower()
        if q:
            out.append(0.0 if q in ("none", "0", "inf") else float(q))
    return out


class Bench:
    def __init__(self, args):
        self.args = args
        self.uri = "http://localhost:%d" % args.port
        self.env = dict(os.environ, ROS_MASTER_URI=self.uri,
                        PATH="/usr/bin:" + os.environ.get("PATH", ""))
        self.env.pop("ROS_NAMESPACE", None)
        self.procs = []          # Popen of this step (killed after it)
        self.groups = []         # CpuQuota of this step
        self.core = None

    # --- processes -------------------------------------------------------------------------
    def popen(self, argv, group=None):
        pre = None
        if group is not None:
            tasks = os.path.join(group.path, "tasks")

            def pre():                       # in the child, before exec: join the group
                with open(tasks, "w") as f:
                    f.write(str(os.getpid()))
        out = subprocess.DEVNULL if not self.args.verbose else None
        p = subprocess.Popen(argv, env=self.env, stdout=out, stderr=out, start_new_session=True,
                             preexec_fn=pre)
        return p

    @staticmethod
    def stop(p, timeout=15.0):
        if p.poll() is not None:
            return
        try:
            os.killpg(p.pid, signal.SIGINT)
            p.wait(timeout)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            try:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                pass

    def start_core(self):
        self.core = self.popen(["roscore", "-p", str(self.args.port)])
        master = xmlrpc.client.ServerProxy(self.uri)
        for _ in range(100):
            try:
                master.getSystemState("/cal")
                return
            except OSError:
                time.sleep(0.2)
        raise RuntimeError("roscore on port %d did not come up" % self.args.port)

    def end_step(self):
        for p in reversed(self.procs):
            self.stop(p)
        self.procs = []
        for g in self.groups:
            try:
                g.remove()
            except OSError as e:
                log("warning: could not remove %s: %s" % (g.path, e))
        self.groups = []

    def close(self):
        self.end_step()
        if self.core is not None:
            self.stop(self.core)
            self.core = None

    # --- parameters --------------------------------------------------------------------------
    def load_params(self, laptop):
        world = os.path.join(PKG, "maps", self.args.world + "_world.yaml")
        params = {"amcl": dict(self.args.amcl_params), "ar_recognition": dict(self.args.ar_params)}
        if laptop:        # robot.launch is not there to set these
            params["amcl"].update(initial_pose_x=START["x"], initial_pose_y=START["y"],
                                  initial_pose_a=START["yaw"], max_update_rate=5.0)
        with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
            yaml.safe_dump(params, f)
        try:
            for ns in ("/amcl", "/ar_recognition"):
                subprocess.run(["rosparam", "delete", ns], env=self.env, capture_output=True)
            subprocess.run(["rosparam", "load", f.name], env=self.env, check=True,
                           capture_output=True)
            if laptop:
                subprocess.run(["rosparam", "load", world, "/ar_recognition"], env=self.env,
                               check=True, capture_output=True)
        finally:
            os.unlink(f.name)

    # --- one step ----------------------------------------------------------------------------
    def step(self, robot_q, laptop_q=None):
        """robot_q: cores of the robot's group (0 = none); laptop_q: None = robot case, else the
        laptop case with AMCL and AR in their own group at laptop_q cores."""
        laptop = laptop_q is not None
        robot = CpuQuota(self.args.cgroup_prefix + "robot", 0)
        robot.create()
        self.groups.append(robot)
        lap = None
        if laptop:
            lap = CpuQuota(self.args.cgroup_prefix + "laptop", 0)
            lap.create()
            self.groups.append(lap)
        self.load_params(laptop)
        self.procs.append(self.popen(["roslaunch", "anyscale_nav_demo", "sim.launch"]))
        flag = "false" if laptop else "true"
        self.procs.append(self.popen(["roslaunch", "anyscale_nav_demo", "robot.launch",
                                      "anyscale:=false", "sim:=false",
                                      "record:=false", "world:=" + self.args.world, "amcl:=" + flag,
                                      "ar_recognition:=" + flag], group=robot))
        if laptop:
            for n in LAPTOP_NODES:
                self.procs.append(self.popen(["/usr/bin/python3", os.path.join(PKG, "nodes", n)],
                                             group=lap))
        time.sleep(self.args.warmup)
        robot.cores = robot_q
        robot.create()                       # rewrites cpu.cfs_quota_us in place
        if lap is not None:
            lap.cores = laptop_q
            lap.create()
        time.sleep(self.args.settle)
        master = xmlrpc.client.ServerProxy(self.uri)
        procs = {}
        for n in ROBOT_NODES + [SIM]:
            pid = node_pid(master, n)
            if pid:
                try:
                    procs[n] = psutil.Process(pid)
                    procs[n].cpu_times()
                except psutil.Error:
                    pass
        t0 = {n: sum(p.cpu_times()[:2]) for n, p in procs.items()}
        thr0 = {g.path: throttle(g) for g in self.groups}
        w0 = time.time()
        # In this process, outside the groups, while the rates are counted: the host's speed
        # these rates were measured at (one window, so every measurement counts).
        host = HostSpeedMonitor(period_s=5.0, window=10000, initial_samples=1, log=log).start()
        try:
            out = subprocess.run(["/usr/bin/python3", "-c", RATE_COUNTER, ",".join(TOPICS),
                                  str(self.args.duration)], env=self.env, capture_output=True,
                                 text=True, timeout=self.args.duration + 60)
        finally:
            host.stop()
        wall = time.time() - w0
        cpu = {}
        for n, p in procs.items():
            try:
                cpu[n] = 100.0 * (sum(p.cpu_times()[:2]) - t0[n]) / wall
            except psutil.Error:
                cpu[n] = float("nan")
        thr = {}
        for g in self.groups:
            a, b = thr0[g.path], throttle(g)
            thr[os.path.basename(g.path)] = (b[0] - a[0], b[1] - a[1])
        try:
            rates = json.loads(out.stdout.strip().splitlines()[-1])
        except (IndexError, ValueError):
            log("rate counter failed: %s" % out.stderr[-500:])
            rates = {t: float("nan") for t in TOPICS}
        self.end_step()
        return {"robot_q": robot_q, "laptop_q": laptop_q, "rates": rates, "cpu": cpu,
                "throttle": thr, "wall": wall, "host_ms": host.median.value,
                "host_samples": list(host.samples)}


def throttle(group):
    """(periods, periods throttled) of a cgroup so far."""
    d = {}
    try:
        with open(os.path.join(group.path, "cpu.stat")) as f:
            for line in f:
                k, v = line.split()
                d[k] = int(v)
    except OSError:
        pass
    return d.get("nr_periods", 0), d.get("nr_throttled", 0)


def node_pid(master, name):
    try:
        code, _, uri = master.lookupNode("/cal", "/" + name)
        if code != 1:
            return None
        code, _, pid = xmlrpc.client.ServerProxy(uri).getPid("/cal")
        return pid if code == 1 else None
    except OSError:
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quotas", default="0.25,0.35,0.5,1.0,none",
                    help="robot group quotas in cores, comma separated ('none' = no quota)")
    ap.add_argument("--laptop-quotas", default="0.6,0.8,1.0",
                    help="laptop group quotas for AMCL + AR alone ('' to skip the laptop case)")
    ap.add_argument("--laptop-robot-quota", default=None,
                    help="robot group quota during the laptop case (default: robot_cpu_cores of "
                         "the calibration file, else none)")
    ap.add_argument("--duration", type=float, default=30.0, help="seconds measured per step")
    ap.add_argument("--warmup", type=float, default=12.0, help="seconds unlimited after start")
    ap.add_argument("--settle", type=float, default=5.0,
                    help="seconds under the quota before measuring")
    ap.add_argument("--port", type=int, default=11643)
    ap.add_argument("--world", default="office_floor")
    ap.add_argument("--cgroup-prefix", default="anyscale_cal_")
    ap.add_argument("--calibration", default=CALIBRATION,
                    help="YAML with amcl/ar_recognition sections (default: the package's)")
    ap.add_argument("--amcl-particles", type=int, help="min_particles = max_particles")
    ap.add_argument("--amcl-beams", type=int, help="laser_max_beams")
    ap.add_argument("--ar-detector-params", help="JSON dict for ar_recognition's ~detector_params")
    ap.add_argument("--verbose", action="store_true", help="show the nodes' output")
    ap.add_argument("--json", metavar="FILE", default=None,
                    help="also write every step's figures there ({robot: [...], laptop: [...]}, "
                         "CPU in %% of one core), e.g. for bench_profile.py's side-by-side run")
    args = ap.parse_args()

    cal = {}
    if args.calibration and os.path.isfile(args.calibration):
        with open(args.calibration) as f:
            cal = yaml.safe_load(f) or {}
    args.amcl_params = dict(cal.get("amcl", {}))
    args.ar_params = dict(cal.get("ar_recognition", {}))
    if args.amcl_particles:
        args.amcl_params.update(min_particles=args.amcl_particles,
                                max_particles=args.amcl_particles)
    if args.amcl_beams:
        args.amcl_params["laser_max_beams"] = args.amcl_beams
    if args.ar_detector_params:
        args.ar_params["detector_params"] = json.loads(args.ar_detector_params)
    robot_qs = parse_quotas(args.quotas)
    laptop_qs = parse_quotas(args.laptop_quotas)
    if args.laptop_robot_quota is not None:
        lr = parse_quotas(args.laptop_robot_quota)[0]
    else:
        lr = float(cal.get("robot_cpu_cores", 0.0) or 0.0)

    if os.geteuid() != 0 or not cgroup_available():
        print("needs root and a writable cgroup v1 CPU hierarchy at /sys/fs/cgroup/cpu",
              file=sys.stderr)
        return 2

    bench = Bench(args)
    results_r, results_l = [], []

    def on_term(*_):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, on_term)
    # Also when started with SIGINT ignored.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    t_start = time.time()
    try:
        log("roscore on port %d; amcl %s; ar_recognition %s"
            % (args.port, args.amcl_params, args.ar_params))
        bench.start_core()
        for q in robot_qs:
            log("robot case: robot group %s cores (%.0f s warm-up, %.0f s settle, %.0f s measured)"
                % (qname(q), args.warmup, args.settle, args.duration))
            r = bench.step(q)
            results_r.append(r)
            log(step_line(r))
        for q in laptop_qs:
            log("laptop case: AMCL + AR in a %s-core group, rest of the robot at %s"
                % (qname(q), qname(lr)))
            r = bench.step(lr, q)
            results_l.append(r)
            log(step_line(r))
    except KeyboardInterrupt:
        log("interrupted; cleaning up")
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not stop the cleanup
        bench.close()

    reference_cpu_ms = cal.get("reference_cpu_ms", "not set")
    print_report(args, psutil.cpu_count(), time.time() - t_start, reference_cpu_ms,
                 results_r, results_l)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"robot": results_r, "laptop": results_l}, f, allow_nan=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
