#!/usr/bin/python3
"""Which configuration keeps the fixed-quota system tests' meaning on a slower host (root; issue
41): side by side, what those tests rely on in each mode, on the small loop at their robot
quota (0.37 cores), in two runs of scripts/run_testbed.py per mode: every node home (the link
down) and AMCL and AR out (a clean 27 Mbit/s link).

Modes (F: how many times slower than the reference day, anyscale_testbed/host_speed.py):
  reference   this host as it is, the calibration's work and quotas
  fixed:F     an emulated host F times slower (run_testbed.py --emulate-slow-host), the
              calibration's work and quotas: a slow day before the slow-day mode
  mode:F      the same host in the slow-day mode for it (--host-factor F)
Per run, after --skip s of start-up: rate and longest gap of /amcl_pose, /ar_markers and the
robot's drivers (/scan, /joint_states, /odom), when the first /amcl_pose came, moves back
(none should come on a clean link), the cores each CPU group used (from /proc, every 2 s) and
their sum against the emulated machine's CPUs (this host's / E), and the share of CFS periods
the robot's and the laptop's groups were throttled in. Results in OUT/slow_host.txt. With the
workspace sourced:
    sudo -E /usr/bin/python3 tests/bench/bench_slow_host.py --modes reference,fixed:4.5,mode:4.5
"""
import argparse
import datetime
import os
import sys
import threading
import time

try:
    from anyscale_testbed.bench_runs import (latest_record, run_logged, save_table,
                                             start_on_the_testbed)
    from anyscale_testbed.host_speed import idle_cpu_ms
    from anyscale_testbed.proc_census import cpu_usage, processes_with_master
    from anyscale_testbed.slow_host_report import format_table, run_figures, throttled_share
    from anyscale_testbed.system_test_gate import EMULATE_ENV, host_mode
    from anyscale_testbed.two_scale_testbed import CGROUP_CPU_ROOT
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUN_TESTBED = os.path.join(ROOT, "scripts", "run_testbed.py")
MASTER_URI = "http://10.213.7.1:11311"      # the bed's robot address (TwoScaleLayout)
CASES = {"home": "[[0, 0]]", "out": "[[0, 27]]"}
ROBOT_CPU = 0.37                            # the fixed-quota system tests' robot quota


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--modes", default="reference,fixed:4.5,mode:4.5,mode:6",
                   help="comma-separated: reference, fixed:F, mode:F (default: %(default)s)")
    p.add_argument("--duration", type=float, default=100.0, help="seconds per run (100)")
    p.add_argument("--skip", type=float, default=30.0, help="start-up left out, s (30)")
    p.add_argument("--out", default=None,
                   help="results directory (default: results/bench_slow_host/<date-time>)")
    args = p.parse_args(argv)
    args.modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    for m in args.modes:
        kind, _, factor = m.partition(":")
        try:
            ok = (kind == "reference" and not factor) or (kind in ("fixed", "mode")
                                                          and float(factor) >= 1)
        except ValueError:
            ok = False
        if not ok:
            p.error(f"--modes: expected reference, fixed:F or mode:F with F >= 1, got {m!r}")
    if args.duration <= args.skip + 10:
        p.error("--duration must be at least --skip + 10 s")
    return args


def mode_argv(mode: str):
    """(run_testbed.py's options, the emulated machine's CPUs, the host mode's description)."""
    if mode == "reference":
        return [], float(os.cpu_count()), "this host"
    kind, factor = mode.split(":")
    host = host_mode(idle_cpu_ms(), {EMULATE_ENV: factor})
    argv = host.argv() if kind == "mode" else host.argv()[2:]
    return argv, os.cpu_count() / host.slowdown, host.describe()


class CpuSampler(threading.Thread):
    """Every 2 s (wall clock): each process of the bed's ROS system (cgroup, CPU seconds), and
    the (nr_periods, nr_throttled) of the robot's and the laptop's CPU groups."""

    def __init__(self):
        super().__init__(daemon=True)
        self.samples, self.stats, self.stop = [], [], threading.Event()

    def run(self):
        while not self.stop.wait(2.0):
            snap = {}
            for pid in processes_with_master(MASTER_URI):
                usage = cpu_usage(pid)
                if usage:
                    snap[pid] = (usage[1], usage[2])
            now = time.time()
            self.samples.append((now, snap))
            self.stats.append((now, {g: cpu_stat(g) for g in ("robot", "laptop")}))

    def throttled(self, start: float):
        window = [s for t, s in self.stats if t >= start and all(s.values())]
        if len(window) < 2:
            return {}
        return {g: throttled_share(window[0][g], window[-1][g]) for g in ("robot", "laptop")}


def cpu_stat(group: str):
    try:
        with open(os.path.join(CGROUP_CPU_ROOT, f"anyscale_{group}", "cpu.stat")) as f:
            stat = dict(line.split() for line in f if line.strip())
        return int(stat["nr_periods"]), int(stat["nr_throttled"])
    except (OSError, KeyError, ValueError):
        return None


def main(argv=None) -> int:
    args = parse_args(argv)
    start_on_the_testbed("bench_slow_host")
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    out = os.path.abspath(args.out or os.path.join(ROOT, "results", "bench_slow_host", stamp))
    rows = []
    try:
        for mode in args.modes:
            extra, machine, described = mode_argv(mode)
            for case, schedule in CASES.items():
                run_dir = os.path.join(out, f"{mode.replace(':', '-')}-{case}")
                print(f"bench: {mode} {case}: {described}; {' '.join(extra)}", flush=True)
                sampler = CpuSampler()
                sampler.start()
                code = run_logged([sys.executable, RUN_TESTBED, "--world", "small_loop",
                                   "--link", "schedule", "--schedule", schedule, "--duration",
                                   str(args.duration), "--loops", "2", "--robot-cpu",
                                   str(ROBOT_CPU), "--record-inputs",
                                   "/scan,/joint_states,/odom", "--out", run_dir] + extra,
                                  run_dir)
                sampler.stop.set()
                sampler.join(5.0)
                rec = latest_record(run_dir)
                if code != 0 or rec is None:
                    print(f"bench: {mode} {case}: the run failed (exit {code}); see "
                          f"{run_dir}/console.log", flush=True)
                    continue
                # the samples' wall clock against the record's (t = 0 at its start)
                samples = [(t - rec.started_wall, snap) for t, snap in sampler.samples]
                rows.append(run_figures(mode, case, rec, samples, args.skip, machine,
                                        sampler.throttled(rec.started_wall + args.skip)))
                print(format_table(rows[-1:]).splitlines()[-1], flush=True)
    except KeyboardInterrupt:
        print("bench: interrupted; the runs that ended:", flush=True)
    save_table(format_table(rows), out, "slow_host.txt")
    return 0


if __name__ == "__main__":
    sys.exit(main())
