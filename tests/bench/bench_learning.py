#!/usr/bin/python3
"""The learning bench (root; issue 40): the main job's scenario with the placement learning (live
cost estimates and back-offs, the default) and without it (run_testbed.py --model-costs: the
allocators plan with the model's figures), on the same world, WiFi seed and quotas, run after
run in pairs, so that the host's drift falls on both alike. Per run: the path time, moves out
and back, returns for rate or CPU, the longest output silence against its tolerance and the
violations; then, per pair, learning against model. Results in OUT/learning.txt.

A run takes about 5 minutes on the office floor and needs the machine to itself. With the
workspace sourced:
    sudo -E /usr/bin/python3 tests/bench/bench_learning.py --pairs 1
"""
import argparse
import datetime
import math
import os
import sys

try:
    from anyscale_testbed.bench_runs import (latest_record, run_logged, save_table,
                                             start_on_the_testbed)
    from anyscale_testbed.calibration_file import quota_cores
    from anyscale_testbed.testbed_record import OTHER_RETURN, TestbedRecord, kind_of_move
    from anyscale_testbed.tolerance_report import path_time
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUN_TESTBED = os.path.join(ROOT, "scripts", "run_testbed.py")
MODES = {"learning": [], "model": ["--model-costs"]}


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--pairs", type=int, default=1, help="pairs of runs (1)")
    p.add_argument("--world", default="office_floor", help="office_floor (default) or small_loop")
    p.add_argument("--seed", type=int, default=1, help="the WiFi variation's seed (1)")
    p.add_argument("--robot-cpu", type=float, default=None,
                   help="the robot's quota in cores (default: the calibration file's)")
    p.add_argument("--laptop-cpu", type=float, default=None,
                   help="the laptop's quota in cores (default: the calibration file's)")
    p.add_argument("--out", default=None,
                   help="results directory (default: results/bench_learning/<date-time>)")
    args = p.parse_args(argv)
    if not 1 <= args.pairs <= 20:
        p.error(f"--pairs: expected 1 to 20, got {args.pairs}")
    if args.seed < 0:
        p.error(f"--seed: expected an integer >= 0, got {args.seed}")
    for name in ("robot_cpu", "laptop_cpu"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            p.error(f"--{name.replace('_', '-')}: expected cores > 0, got {value:g}")
    return args


def run_figures(rec: TestbedRecord) -> dict:
    """What the bench compares of one run."""
    moves = [e for e in rec.events if e.kind in ("migrate", "migrate_back") and e.success]
    return {
        "path_s": path_time(rec),
        "out": sum(e.kind == "migrate" for e in moves),
        "back": sum(e.kind == "migrate_back" for e in moves),
        # planned returns that were not the link's: the scale could not give the node its rate
        # or CPU (the learning's back-off names itself in the reason; without it, the same)
        "rate_cpu": sum(kind_of_move(e) == OTHER_RETURN and not e.reason.startswith("bandwidth")
                        for e in moves),
        "violations": len(rec.violations),
    }


def format_rows(rows) -> str:
    lines = [f"{'pair':>4} {'mode':<9} {'path s':>7} {'out':>4} {'back':>5} "
             f"{'rate/CPU':>9} {'violations':>10}"]
    for pair, mode, f in rows:
        lines.append(f"{pair:>4} {mode:<9} {f['path_s']:7.1f} {f['out']:>4} {f['back']:>5} "
                     f"{f['rate_cpu']:>9} {f['violations']:>10}")
    by_pair = {}
    for pair, mode, f in rows:
        by_pair.setdefault(pair, {})[mode] = f
    for pair, modes in sorted(by_pair.items()):
        if len(modes) == 2:
            a, b = modes["learning"], modes["model"]
            ratio = a["path_s"] / b["path_s"]
            lines.append(f"pair {pair}: learning / model path time {ratio:.3f}; "
                         f"moves {a['out'] + a['back']} / {b['out'] + b['back']}")
    return "\n".join(lines)


def main(argv=None) -> int:
    args = parse_args(argv)
    start_on_the_testbed("bench_learning")
    robot_cpu, laptop_cpu = quota_cores(args.robot_cpu, args.laptop_cpu)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    out = os.path.abspath(args.out or os.path.join(ROOT, "results", "bench_learning", stamp))
    rows = []
    try:
        for pair in range(1, args.pairs + 1):
            # Alternate which mode goes first: a drift within a pair falls on each alike.
            order = list(MODES) if pair % 2 else list(MODES)[::-1]
            for mode in order:
                run_dir = os.path.join(out, f"pair{pair}-{mode}")
                print(f"bench: pair {pair}/{args.pairs}, {mode}: {args.world}, seed {args.seed}, "
                      f"robot {robot_cpu:g} / laptop {laptop_cpu:g} cores; {run_dir}", flush=True)
                code = run_logged([sys.executable, RUN_TESTBED, "--world", args.world, "--link",
                                   "coverage", "--seed", str(args.seed), "--robot-cpu",
                                   str(robot_cpu), "--laptop-cpu", str(laptop_cpu), "--out",
                                   run_dir] + MODES[mode], run_dir)
                rec = latest_record(run_dir)
                if code != 0 or rec is None:
                    print(f"bench: pair {pair}, {mode}: the run failed (exit {code}); see "
                          f"{run_dir}/console.log", flush=True)
                    continue
                rows.append((pair, mode, run_figures(rec)))
                print(format_rows(rows[-1:]).splitlines()[-1], flush=True)
    except KeyboardInterrupt:
        print("bench: interrupted; the runs that ended:", flush=True)
    save_table(format_rows(rows), out, "learning.txt")
    return 0


if __name__ == "__main__":
    sys.exit(main())
