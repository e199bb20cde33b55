"""The navigation demo on the two-scale test bed with AnyScale deciding.

The robot and the laptop are network namespaces joined by a veth pair whose bandwidth follows a
WiFi coverage model of the floor (or a scripted schedule); each scale's processes run under a
cgroup CPU quota. The robot runs the master, the simulator, its agent and the decision node; the
laptop runs its agent. Mapping changes are printed as they happen and a table at the end.
Without root, namespaces or cgroups it says so and runs both scales on loopback, unshaped.
With --scales robot,laptop,server a server joins them behind the WiFi's access point, on a
wired segment (access_point_layout.py), with its agent and CPU quota (scale_set.py).

This is the logic of scripts/run_testbed.py (the main job's second half). Run it with the
workspace sourced (scripts/run_demo.sh does that):
    sudo -E scripts/run_testbed.py                      # office floor, WiFi coverage model
    scripts/run_testbed.py --link schedule --schedule '[[0, 27], [40, 3], [60, 0], [75, 27]]'
    sudo -E scripts/run_testbed.py --start-goal 1      # the same loop, from the world's goal 1
    sudo -E scripts/run_testbed.py --normalise-cpu     # quotas follow the host's speed
    sudo -E scripts/run_testbed.py --scales robot,laptop,server   # and a server
"""
import argparse
import contextlib
import datetime
import os
import shutil
import signal
import sys
from typing import Optional, Tuple

import yaml

from anyscale_core.link_map import LinkMapError, load_link_map
from anyscale_testbed.calibration_file import (calibrated_reference_ms, nav_demo_path,
                                               quota_cores)
from anyscale_testbed.demo_launch import LINK_MAP, PREFIX, launch_demo, world_start
from anyscale_testbed.host_speed import (REFERENCE_IDLE_MS, CpuNormaliser, host_factor,
                                         idle_cpu_ms)
from anyscale_testbed.quota_calibration import MAX_RUNS, CalibrationError
from anyscale_testbed.quota_for_the_day import CALIBRATION_RUN_S, QuotaForTheDay, parse_robot_cpu
from anyscale_testbed.scale_set import (MODEL_FILES, SERVER_CPU_CORES, THREE_SCALES,
                                        bed_layout, check_server_cpu, fit_problem, model_problem,
                                        parse_scales, quota_words, scale_cores,
                                        slow_day_server_cores)
from anyscale_testbed.slow_host import check_factor, describe, emulated_host, slow_day_mode
from anyscale_testbed.testbed_record import (TestbedRecord, mark_interrupted,
                                             store_cpu_normalisation)
from anyscale_testbed.testbed_session import LoopbackBed, NamespaceBed, TestbedSession
from anyscale_testbed.two_scale_testbed import CFS_PERIOD_US, TwoScaleError, missing_capabilities

# --normalise-cpu: the quotas stay as calibrated this long after the bed is up. The robot's
# node set takes 15-17 s to come up under its quota, and the workload measures the host as its
# nodes load it (host_speed.HostSpeedMonitor).
NORMALISE_SETTLE_S = 30.0


def parse_args(argv, default_out: str):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--world", default="office_floor", help="office_floor (default), small_loop")
    p.add_argument("--link", choices=("coverage", "schedule", "unshaped"), default="coverage",
                   help="coverage: bandwidth from the robot's position (default); schedule: "
                        "--schedule over time; unshaped: no shaping at all")
    p.add_argument("--schedule", default="[[0, 27]]",
                   help="[[t_s, Mbit/s], ...] for --link schedule; 0 Mbit/s = link down")
    p.add_argument("--seed", type=int, default=0, metavar="N",
                   help="--link coverage: seeded shadowing and interference episodes on the WiFi "
                        "model (wifi_variation.py); 0 (default) = the deterministic model")
    p.add_argument("--start-goal", type=int, default=None, metavar="K",
                   help="start at goal K of the world's goal list (0 = the first) and do the "
                        "loop from there, round to goal K (default: the world's start)")
    p.add_argument("--loops", type=int, default=1, metavar="N",
                   help="drive the loop N times (default 1); the run ends when the last is done "
                        "or after --duration")
    p.add_argument("--duration", type=float, default=0.0,
                   help="end after this many seconds (default: when the loop is done)")
    p.add_argument("--robot-cpu", default=None, metavar="CORES|auto",
                   help="robot CPU quota (default: the calibration file's). auto (what "
                        f"scripts/run_demo.sh passes): before the run, 1-{MAX_RUNS} short runs "
                        f"with every node home and the link down ({CALIBRATION_RUN_S:g} s each) "
                        "find the quota at which "
                        "AMCL runs the premise's 2 Hz at this moment, as the paper's robot did; "
                        "this host's speed drifts, so a fixed quota held the premise only on the "
                        "day it was measured. The run then uses it; it is printed, so that a "
                        "next run can be given it")
    p.add_argument("--laptop-cpu", type=float, default=None, metavar="CORES",
                   help="laptop CPU quota (default: the calibration file's)")
    p.add_argument("--scales", default="robot,laptop", metavar="LIST",
                   help="robot,laptop (default), or robot,laptop,server: a server behind the "
                        "WiFi's access point on a 100 Mbit/s wired segment, with its agent in "
                        "its own namespace and CPU quota (--server-cpu), and anyscale_nav_demo's "
                        f"config/{MODEL_FILES[THREE_SCALES]} unless --model "
                        "(anyscale_testbed/access_point_layout.py)")
    p.add_argument("--server-cpu", type=float, default=None, metavar="CORES",
                   help=f"--scales ...,server: the server's CPU quota (default "
                        f"{SERVER_CPU_CORES:g}, 1.5 x the robot's calibrated quota as in the "
                        "model; all quotas together must leave the world 0.2 cores of this host)")
    p.add_argument("--normalise-cpu", action="store_true",
                   help="scale both CPU quotas with the host's speed: every run times a fixed "
                        "workload (anyscale_testbed/host_speed.py) every 5 s and records its "
                        "CPU ms (cpu_normalisation); with this option each quota is also set to "
                        "its cores x the workload's median ms / the ms at which the quota was "
                        "found (--reference-cpu-ms), so that each scale gets the work per second "
                        "done that it had then. Why: this host is a shared VM whose speed "
                        "drifts; at the same 0.34 cores AMCL with every node home ran 3.18 to "
                        "1.77 Hz over 7 runs as the workload took 11.8-16.5 ms. Off by default; "
                        "see the anyscale_testbed README")
    p.add_argument("--reference-cpu-ms", type=float, default=None, metavar="MS",
                   help="--normalise-cpu: the workload's CPU ms, timed the same way, at which "
                        "--robot-cpu was found (bench_tolerances.py and run_evaluation.py pass "
                        "their calibration's). Default: with --robot-cpu auto, the calibration "
                        "run's own; else the calibration file's reference_cpu_ms")
    p.add_argument("--host-factor", default="1", metavar="auto|F",
                   help="the system tests' slow-day mode: run as on a host F times slower than "
                        "the reference day (F >= 1; auto: this host's idle reading of "
                        "anyscale_testbed/host_speed.py's workload over its reference, "
                        f"{REFERENCE_IDLE_MS:g} ms): AMCL's particles and AR recognition's "
                        "threshold windows divided by F in a copy of the calibration file, the "
                        "quotas raised by what the unscaled nodes need more "
                        "(anyscale_testbed/slow_host.py). Default 1: the calibration as it is")
    p.add_argument("--emulate-slow-host", type=float, default=1.0, metavar="E",
                   help="test bed only, an EMULATION of a host E times slower than this one: "
                        "every CPU quota divided by E, and the world (simulator, monitor, "
                        "master) held in a CPU group of this machine's CPUs / E "
                        "(anyscale_testbed/slow_host.py). CFS hands quotas out in bursts, a "
                        "slow CPU does not. Default 1: none")
    p.add_argument("--cfs-period-ms", type=float, default=CFS_PERIOD_US / 1000, metavar="MS",
                   help="the CPU quotas' CFS period, 1-1000 ms (default: the kernel's 100). A "
                        "group that used its quota waits for the next period; 10 ms was "
                        "measured worse than 100 (the drivers' and AMCL's longest gaps doubled: "
                        "the kernel hands quota out in 5 ms slices), see two_scale_testbed.py")
    p.add_argument("--record-inputs", default="", metavar="TOPICS",
                   help="comma-separated topics whose receipts the record keeps too, e.g. "
                        "/scan,/odom,/odometry/filtered: each tolerance violation's cause then "
                        "gives their longest gaps, so a node starved of its inputs is told from "
                        "one slow on them. Each is one more subscriber that the robot's "
                        "publishers serve on the robot's quota; never name a heavy stream (the "
                        "camera) (default: none)")
    p.add_argument("--allocator", default="paper", help="paper (default), paper_local, optimal")
    p.add_argument("--hysteresis", type=float, default=10.0, help="the paper's T in s (10)")
    p.add_argument("--hold-after-loss", type=float, default=None, metavar="S",
                   help="after a link loss, no node but AMCL moves out until the link has been "
                        "up this long (default: robot.launch's, 20; AMCL's own: "
                        "--amcl-hold-after-loss)")
    p.add_argument("--amcl-hold-after-loss", type=float, default=None, metavar="S",
                   help="AMCL's own hold after a link loss (default: robot.launch's, 0: only "
                        "the bandwidth hold; 20 gives the rule of the evaluation of 2026-11-27)")
    p.add_argument("--weak-link-mbps", type=float, default=None, metavar="MBPS",
                   help="robot.launch's weak_link_mbps: a link measured below this carries "
                        "nothing (default: robot.launch's, 5.5; 0: off, as the small loop's "
                        "3-4.5 Mbit/s coverage needs for AMCL to move out at all)")
    p.add_argument("--late-boost-fraction", type=float, default=None, metavar="F",
                   help="robot.launch's late_boost_fraction: a node on the robot whose output "
                        "stays silent for F x its tolerance runs at the start boost's nice until "
                        "its next message (default: robot.launch's, 0.5; 0: none, to compare)")
    p.add_argument("--model-costs", action="store_true",
                   help="the decision node plans with the model's cpu_usage alone, not with the "
                        "costs it learns while the nodes run (robot.launch's learn_costs:=false; "
                        "to compare)")
    p.add_argument("--no-forecast", action="store_true",
                   help="robot.launch's link_forecast:=false: the reactive rules only, no moves "
                        "out early nor planned returns before a hole (to compare); the link "
                        "map is still learned. Always so with --link schedule or unshaped: "
                        "their link follows the clock, not the robot's place")
    p.add_argument("--link-map", default=None, metavar="FILE",
                   help="start from the link map in FILE (an earlier run's RUN_DIR/link_map.yaml"
                        "), copied into this run's directory (default: an empty map); the run "
                        "saves what it learned in RUN_DIR/link_map.yaml")
    p.add_argument("--save-link-map", default=None, metavar="FILE",
                   help="also copy the link map the run learned to FILE at its end")
    p.add_argument("--model", default=None, help="system model (default: the nav demo's)")
    p.add_argument("--cold-start", action="store_true",
                   help="agents keep no warm standbys: every start imports anew (to compare)")
    p.add_argument("--rviz", action="store_true", help="also start rviz (needs a display)")
    p.add_argument("--loopback", action="store_true",
                   help="both scales on loopback, unshaped, even where namespaces work")
    p.add_argument("--out", default=default_out,
                   help="results directory (a subdirectory per run)")
    args = p.parse_args(argv)
    try:
        schedule = yaml.safe_load(args.schedule)
        assert isinstance(schedule, list) and all(
            isinstance(s, list) and len(s) == 2 for s in schedule)
    except (yaml.YAMLError, AssertionError):
        p.error(f"--schedule: expected [[t_s, Mbit/s], ...], got {args.schedule!r}")
    if args.seed < 0:
        p.error(f"--seed: expected an integer >= 0, got {args.seed}")
    try:
        args.scales = parse_scales(args.scales)
        check_server_cpu(args.server_cpu, args.scales)
    except ValueError as e:
        p.error(str(e))
    if args.weak_link_mbps is not None and not 0 <= args.weak_link_mbps < 1000:
        p.error(f"--weak-link-mbps: expected 0 or more Mbit/s, got {args.weak_link_mbps:g}")
    if args.late_boost_fraction is not None and not 0 <= args.late_boost_fraction <= 1:
        p.error(f"--late-boost-fraction: expected 0-1, got {args.late_boost_fraction:g}")
    args.calibrate_robot_cpu = args.robot_cpu == "auto"
    if args.reference_cpu_ms is not None and not (args.normalise_cpu
                                                  and 0 < args.reference_cpu_ms < 1000):
        p.error("--reference-cpu-ms: expected 0-1000 ms with --normalise-cpu, got "
                f"{args.reference_cpu_ms:g}"
                + ("" if args.normalise_cpu else " without --normalise-cpu"))
    if args.calibrate_robot_cpu and args.reference_cpu_ms is not None:
        p.error("--reference-cpu-ms: --robot-cpu auto measures its own")
    try:
        args.robot_cpu = parse_robot_cpu(args.robot_cpu) if args.robot_cpu else None
    except ValueError as e:
        p.error(str(e))
    if not 1 <= args.loops <= 100:
        p.error(f"--loops: expected 1 to 100, got {args.loops}")
    if not 1 <= args.cfs_period_ms <= 1000:
        p.error("--cfs-period-ms: expected 1 to 1000 ms (the kernel's limits), got "
                f"{args.cfs_period_ms:g}")
    try:
        check_factor(args.emulate_slow_host, "--emulate-slow-host")
        if args.host_factor != "auto":
            args.host_factor = check_factor(float(args.host_factor), "--host-factor")
    except ValueError as e:
        p.error(str(e) if "factor" in str(e) else
                f"--host-factor: expected auto or a factor >= 1, got {args.host_factor!r}")
    if args.host_factor != 1 and (args.normalise_cpu or args.calibrate_robot_cpu):
        p.error("--host-factor: not with --normalise-cpu or --robot-cpu auto (each sets the "
                "quotas from the host's speed its own way)")
    if args.emulate_slow_host > 1 and (args.normalise_cpu or args.calibrate_robot_cpu):
        p.error("--emulate-slow-host: not with --normalise-cpu or --robot-cpu auto (they "
                "measure this host, not the emulated one)")
    if args.seed and args.link != "coverage":
        p.error("--seed varies the coverage model: it needs --link coverage")
    if args.link_map is not None:
        try:
            load_link_map(args.link_map)
        except LinkMapError as e:
            p.error(f"--link-map: {e}")
    args.record_inputs = [t.strip() for t in args.record_inputs.split(",") if t.strip()]
    bad = [t for t in args.record_inputs if not t.startswith("/") or " " in t]
    if bad:
        p.error(f"--record-inputs: expected resolved topic names such as /scan, got {bad[0]!r}")
    return args


def main(default_out: str, run_testbed: str, argv=None) -> int:
    """One run; `default_out` is where --out defaults to (the caller's results/testbed),
    `run_testbed` the script that runs this (--robot-cpu auto runs it for its calibration)."""
    args = parse_args(argv, default_out)
    model = args.model or nav_demo_path("config", MODEL_FILES[args.scales])
    robot_cpu, laptop_cpu = quota_cores(args.robot_cpu, args.laptop_cpu)
    server_cpu = None               # two scales
    if args.scales == THREE_SCALES:
        server_cpu = SERVER_CPU_CORES if args.server_cpu is None else args.server_cpu
        problem = model_problem(model, args.scales)
        if problem:
            print(f"run_testbed: {problem}", file=sys.stderr)
            return 2
    reference_ms = args.reference_cpu_ms
    if args.normalise_cpu and reference_ms is None and not args.calibrate_robot_cpu:
        reference_ms = calibrated_reference_ms(nav_demo_path("config",
                                                             "testbed_calibration.yaml"))
    (x, y, yaw), goals = world_start(args.world, args.start_goal, args.loops)

    missing = [] if args.loopback else missing_capabilities()
    loopback = args.loopback or bool(missing)
    link = "unshaped" if loopback else args.link
    if missing:
        print(PREFIX + "this machine lacks " + "; ".join(missing) + ".")
    if loopback:
        print(PREFIX + "running both scales on loopback: the link is NOT shaped and the CPUs "
              "are NOT limited, so this is not emulated WiFi. Migrations still happen for real.")
        if args.normalise_cpu:
            print(PREFIX + "--normalise-cpu: no CPU quotas on loopback, nothing to normalise")

    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    start = "" if args.start_goal is None else f"-goal{args.start_goal}"
    seed = f"-seed{args.seed}" if args.seed and link == "coverage" else ""
    run_dir = os.path.abspath(os.path.join(args.out,
                                           f"{args.world}{start}-{link}{seed}-{stamp}"))
    record = os.path.join(run_dir, "record.json")
    # Ctrl-C and a plain kill both end in the teardown of the bed (or of a calibration run's).
    signal.signal(signal.SIGTERM, raise_interrupt)
    if args.calibrate_robot_cpu and loopback:
        print(PREFIX + "--robot-cpu auto: no CPU quotas on loopback, nothing to calibrate")
    elif args.calibrate_robot_cpu:
        try:
            robot_cpu, found_at_ms = quota_for_this_moment(run_testbed, args, run_dir)
        except (CalibrationError, KeyboardInterrupt) as e:
            print(PREFIX + f"--robot-cpu auto: {str(e) or 'interrupted'}; no run")
            return 1 if isinstance(e, CalibrationError) else 130
        if args.normalise_cpu and found_at_ms is None:
            print(PREFIX + "--normalise-cpu: the calibration timed no host speed; the quotas "
                  "stay as found")
        reference_ms = found_at_ms
    mode = None
    factor = host_factor(idle_cpu_ms()) if args.host_factor == "auto" else args.host_factor
    if factor > 1 and not loopback:
        mode = slow_day_mode(factor, robot_cpu, laptop_cpu, read_calibration())
        robot_cpu, laptop_cpu = mode.robot_cores, mode.laptop_cores
        if server_cpu is not None:
            server_cpu = slow_day_server_cores(server_cpu, factor)
        print(PREFIX + describe(mode))
    emulated = None
    if args.emulate_slow_host > 1 and not loopback:
        emulated = emulated_host(args.emulate_slow_host, robot_cpu, laptop_cpu, os.cpu_count())
        robot_cpu, laptop_cpu = emulated.robot_cores, emulated.laptop_cores
        if server_cpu is not None:
            server_cpu /= emulated.slowdown
        print(PREFIX + f"EMULATING a host {emulated.slowdown:g} x slower than this one: the "
              f"quotas divided by {emulated.slowdown:g}, "
              f"the world in {emulated.world_cores:.3f} cores")
    cores = scale_cores(robot_cpu, laptop_cpu, server_cpu)
    # Two scales fitted this host by calibration; a third quota may not (scale_set.fit_problem).
    unfit = fit_problem(cores, os.cpu_count() or 1) if server_cpu and not loopback else ""
    if unfit:
        print(f"run_testbed: {unfit}", file=sys.stderr)
        return 2
    bed = LoopbackBed() if loopback else NamespaceBed(
        bed_layout(cores, link), cfs_period_us=int(args.cfs_period_ms * 1000),
        world_cores=emulated.world_cores if emulated else 0.0)
    normaliser = None
    if not loopback:
        # Every run times its host's speed (the record's cpu_normalisation: a calibration run's
        # is the reference of the runs at its quota); only --normalise-cpu moves the quotas.
        # The groups exist once the bed is entered; the normaliser is entered after it and left
        # before it, so it never writes to a group the teardown is removing.
        normaliser = CpuNormaliser(bed.quotas, cores,
                                   reference_ms, settle_s=NORMALISE_SETTLE_S,
                                   follow=args.normalise_cpu and reference_ms is not None,
                                   log=lambda line: print(PREFIX + line, flush=True))
    following = normaliser is not None and normaliser.follow
    print(PREFIX + f"world {args.world}, link {link}" + (f" seed {args.seed}" if seed else "")
          + ("" if loopback else f", {quota_words(cores)} per {args.cfs_period_ms:g} ms period")
          + (f" at the host speed of the calibration ({reference_ms:g} ms workload), "
             "normalised every 5 s" if following else "")
          + f"; logs and results in {run_dir}")

    if args.link_map:
        os.makedirs(run_dir, exist_ok=True)
        shutil.copyfile(args.link_map, os.path.join(run_dir, LINK_MAP))
        print(PREFIX + f"link map: starting from {args.link_map}")
    interrupted = False
    try:
        with bed, (normaliser or contextlib.nullcontext()):
            if following:
                print(PREFIX + normaliser_state(normaliser), flush=True)
            session = TestbedSession(bed, run_dir)
            world = launch_demo(session, bed, args, model, (x, y, yaw), goals, record, run_dir,
                                link, mode=mode)
            code = world.wait()
            print(PREFIX + f"run ended (world launch exit {code}); stopping both scales")
            cut_short = ended_early(record)
            if cut_short:
                print(f"run_testbed: {cut_short}; see {os.path.join(run_dir, 'logs', 'world.log')}",
                      file=sys.stderr)
            return 0 if code == 0 and not cut_short else 1
    except KeyboardInterrupt:
        print(PREFIX + "interrupted: stopping both scales and removing the test bed")
        interrupted = True
        return 130
    except TwoScaleError as e:
        print(f"run_testbed: {e}", file=sys.stderr)
        return 1
    finally:
        # After the bed's teardown: the monitor, which writes the record, has ended.
        if normaliser and os.path.exists(record):
            try:
                store_cpu_normalisation(record, normaliser.history_copy(),
                                        reference_ms if following else None)
            except (OSError, ValueError, TypeError, KeyError) as e:
                print(PREFIX + f"the quotas' history is not in the record: {e}")
        if interrupted and os.path.exists(record):
            try:
                mark_interrupted(record)
            except (OSError, ValueError, TypeError, KeyError) as e:
                print(PREFIX + f"the record does not say that the run was interrupted: {e}")
        if os.path.exists(record):
            print(PREFIX + f"record: {record}")
        keep_link_map(run_dir, args.save_link_map)


def ended_early(record: str) -> str:
    """Why a run that was not interrupted ended before its loops and its duration ('' if it did
    not): roslaunch exits 0 when a required node dies, so its exit code alone cannot tell."""
    try:
        rec = TestbedRecord.load(record)
    except (OSError, ValueError, TypeError, KeyError) as e:
        return f"the run left no readable record ({record}: {e})"
    if rec.ended_by == "shutdown":
        return (f"the run ended after {rec.finished_t or 0.0:.1f} s, before its loops were done "
                "and before its duration: a required node of the world (the simulator, the link "
                "shaper) or the master ended")
    return ""


def keep_link_map(run_dir: str, to: Optional[str]):
    """The map the run learned, copied to `to` (--save-link-map), whole or not at all."""
    learned = os.path.join(run_dir, LINK_MAP)
    if not to:
        return
    if not os.path.exists(learned):
        print(PREFIX + f"--save-link-map: the run saved no link map ({learned})")
        return
    try:
        shutil.copyfile(learned, to + ".tmp")
        os.replace(to + ".tmp", to)
        print(PREFIX + f"link map: {to}")
    except OSError as e:
        print(PREFIX + f"--save-link-map: cannot write {to}: {e}")


def quota_for_this_moment(run_testbed: str, args, run_dir: str) -> Tuple[float, Optional[float]]:
    """--robot-cpu auto: the robot's quota at which AMCL runs the premise's rate with every node
    home, found by short runs kept in run_dir/robot_quota/ (quota_for_the_day.py), and the host
    speed (workload CPU ms) it was found at, None if its runs timed none."""
    print(PREFIX + "--robot-cpu auto: finding the robot's CPU quota at which AMCL runs its "
          f"2 Hz minimum with every node home (the paper's premise), by 1-{MAX_RUNS} runs of "
          f"{CALIBRATION_RUN_S:g} s with the link down; --robot-cpu CORES skips this",
          flush=True)
    quotas = QuotaForTheDay(run_testbed, args.world, run_dir,
                            extra_argv=["--cfs-period-ms", f"{args.cfs_period_ms:g}"] + (
                                ["--record-inputs", ",".join(args.record_inputs)]
                                if args.record_inputs else []) + (
                                ["--model", args.model] if args.model else []),
                            log=lambda line: print(PREFIX + line, flush=True))
    return quotas.quota("robot_quota"), quotas.found_at_ms("robot_quota")


def read_calibration() -> dict:
    path = nav_demo_path("config", "testbed_calibration.yaml")
    try:
        with open(path) as f:
            return yaml.safe_load(f) or {}
    except (OSError, yaml.YAMLError) as e:
        sys.exit(f"run_testbed: {path}: {e}")


def normaliser_state(normaliser: CpuNormaliser) -> str:
    quotas = ", ".join(f"{scale} {cores:.3f}" for scale, cores in normaliser.cores.items())
    return (f"host speed: CPU quota {quotas or 'none'} cores, as calibrated, until the nodes "
            f"have run {normaliser.settle_s:g} s; then every 5 s, from the workload's median "
            f"CPU ms (calibrated at {normaliser.reference_cpu_ms:g} ms)")


def raise_interrupt(*_):
    raise KeyboardInterrupt
