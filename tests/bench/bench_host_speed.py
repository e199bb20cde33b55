#!/usr/bin/python3
"""Benchmark (root; issues 12 and 13, the premise): does --normalise-cpu hold the robot at the
speed it was calibrated to while this shared VM's speed drifts? Side by side in one run.

It finds the robot's quota for this moment as every run of the main job does (--robot-cpu
auto: 1-3 short runs with every node home until AMCL runs 2-2.3 Hz), which also times the
host's speed (anyscale_testbed/host_speed.py's workload, in ms of CPU) at that quota. Then,
in --rounds rounds, two runs of scripts/run_testbed.py with every node home (the link down,
office floor) at that quota: one with the quota fixed, one with --normalise-cpu
--reference-cpu-ms (the quota follows the workload's ms relative to the calibration's). The
order alternates round by round (fixed first, then normalised first), so a drift over the
bench meets both alike.

Per run: AMCL's rate with every node home (after the start-up), its longest silence, the
workload's median ms and the robot's quota over the run. The summary gives, per condition,
how far AMCL's rate strayed from the calibration's (mean and worst |Hz - calibrated Hz|, the
lowest rate, the longest silence against AMCL's Δ of 2 s), and the ratio of the two mean
deviations (normalised / fixed: below 1, normalising holds the premise closer).

    sudo -E /usr/bin/python3 tests/bench/bench_host_speed.py --rounds 6
    sudo -E /usr/bin/python3 tests/bench/bench_host_speed.py --rounds 2 --duration 120 \\
        --robot-cpu 0.25 --reference-cpu-ms 7
"""
import argparse
import datetime
import math
import os
import statistics
import sys
import time
from dataclasses import dataclass
from typing import List

try:
    from anyscale_testbed.bench_runs import latest_record, run_logged, start_on_the_testbed
    from anyscale_testbed.premise_figures import (START_UP_S, figures_with_every_node_home,
                                                  longest_gap_after)
    from anyscale_testbed.quota_calibration import CalibrationError
    from anyscale_testbed.quota_for_the_day import (CALIBRATION_FILE, EVERY_NODE_HOME_LINK,
                                                    QuotaForTheDay, calibration_markdown,
                                                    host_cpu_ms_measured, normalise_cpu_argv,
                                                    parse_robot_cpu, read_calibration)
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUN_TESTBED = os.path.join(ROOT, "scripts", "run_testbed.py")
CONDITIONS = ("fixed", "normalised")


@dataclass
class HomeRun:
    round: int
    condition: str                  # fixed or normalised
    amcl_hz: float = math.nan       # with every node home, after the start-up
    longest_gap_s: float = math.nan
    host_ms: float = math.nan       # the workload's median over the run
    robot_cores: tuple = ()         # (lowest, highest) quota the run had


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--rounds", type=int, default=6,
                   help="rounds of two runs, one fixed and one normalised (6)")
    p.add_argument("--duration", type=float, default=150.0,
                   help=f"seconds per run (150; the first {START_UP_S:g} are start-up)")
    p.add_argument("--robot-cpu", default="auto", metavar="CORES|auto",
                   help="the robot's quota (auto, the default: found now, as the main job "
                        "does; a given quota needs --reference-cpu-ms)")
    p.add_argument("--reference-cpu-ms", type=float, default=None, metavar="MS",
                   help="with a given --robot-cpu: the host speed it was found at")
    p.add_argument("--out", default=None,
                   help="results directory (default: results/bench_host_speed/<date-time>)")
    args = p.parse_args(argv)
    if not 1 <= args.rounds <= 50:
        p.error(f"--rounds: expected 1 to 50, got {args.rounds}")
    if args.duration <= START_UP_S + 30:
        p.error(f"--duration: expected more than {START_UP_S + 30:g} s (the start-up and 30 s "
                f"of AMCL at home), got {args.duration:g}")
    try:
        args.robot_cpu = parse_robot_cpu(args.robot_cpu)
    except ValueError as e:
        p.error(str(e))
    if (args.robot_cpu is None) != (args.reference_cpu_ms is None):
        p.error("--robot-cpu CORES and --reference-cpu-ms MS go together (auto measures both)")
    if args.reference_cpu_ms is not None and not 0 < args.reference_cpu_ms < 1000:
        p.error(f"--reference-cpu-ms: expected 0-1000 ms, got {args.reference_cpu_ms:g}")
    return args


def run_order(rounds: int) -> List[tuple]:
    """(round, condition) in the order run: fixed first in odd rounds, normalised first in even
    ones, so that a steady drift weighs on both conditions alike."""
    order = []
    for k in range(1, rounds + 1):
        pair = CONDITIONS if k % 2 else CONDITIONS[::-1]
        order += [(k, c) for c in pair]
    return order


def run_argv(condition: str, quota: float, reference_ms: float, duration: float,
             out_dir: str) -> List[str]:
    return ([sys.executable, RUN_TESTBED, "--world", "office_floor", "--duration",
             f"{duration:g}", "--robot-cpu", f"{quota:g}", "--out", out_dir]
            + EVERY_NODE_HOME_LINK
            + normalise_cpu_argv(condition == "normalised", reference_ms))


def home_run(round_: int, condition: str, rec) -> HomeRun:
    run = HomeRun(round_, condition)
    if rec is None:
        return run
    row = figures_with_every_node_home(rec, START_UP_S)
    if row:
        run.amcl_hz = row["amcl_hz"]
    run.longest_gap_s = longest_gap_after(rec.receipts.get("/amcl_pose", []), START_UP_S)
    run.host_ms = host_cpu_ms_measured(rec) or math.nan
    cores = [robot for _, robot, _, _ in rec.cpu_normalisation]
    run.robot_cores = (min(cores), max(cores)) if cores else ()
    return run


def run_line(run: HomeRun) -> str:
    cores = (f"{run.robot_cores[0]:.3f}-{run.robot_cores[1]:.3f}" if run.robot_cores else "-")
    return (f"round {run.round} {run.condition:10s} AMCL {run.amcl_hz:.2f} Hz at home, longest "
            f"silence {run.longest_gap_s:.2f} s, host {run.host_ms:.1f} ms, robot {cores} cores")


def summary_lines(runs: List[HomeRun], calibrated_hz: float) -> List[str]:
    """Per condition: mean and worst |Hz - calibrated|, lowest rate, longest silence; then the
    ratio of the mean deviations, normalised / fixed."""
    lines, mean_dev = [], {}
    for c in CONDITIONS:
        hz = [r.amcl_hz for r in runs if r.condition == c and math.isfinite(r.amcl_hz)]
        gaps = [r.longest_gap_s for r in runs if r.condition == c
                and math.isfinite(r.longest_gap_s)]
        if not hz:
            lines.append(f"{c:10s}: no run measured")
            continue
        dev = [abs(h - calibrated_hz) for h in hz]
        mean_dev[c] = statistics.mean(dev)
        lines.append(f"{c:10s}: {len(hz)} runs, AMCL {statistics.mean(hz):.2f} Hz at home "
                     f"(lowest {min(hz):.2f}), |Hz - calibrated {calibrated_hz:.2f}| mean "
                     f"{mean_dev[c]:.2f} worst {max(dev):.2f}; longest silence "
                     f"{max(gaps):.2f} s (Δ 2 s)")
    if len(mean_dev) == 2 and mean_dev["fixed"] > 0:
        lines.append(f"normalised / fixed, mean deviation from the calibrated rate: "
                     f"{mean_dev['normalised'] / mean_dev['fixed']:.2f}")
    return lines


def main(argv=None) -> int:
    args = parse_args(argv)
    start_on_the_testbed("bench")
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    out = os.path.abspath(args.out or os.path.join(ROOT, "results", "bench_host_speed", stamp))
    os.makedirs(out, exist_ok=True)
    order = run_order(args.rounds)
    print(f"bench: calibration, then {len(order)} runs of {args.duration:g} s with every node "
          f"home (about {len(order) * (args.duration + 25) / 60:.0f} min); results in {out}",
          flush=True)
    quotas = QuotaForTheDay(RUN_TESTBED, "office_floor", out, args.robot_cpu)
    try:
        quota = quotas.quota("calibration")
        reference_ms = args.reference_cpu_ms or quotas.found_at_ms("calibration")
    except CalibrationError as e:
        print(f"bench: {e}", flush=True)
        return 1
    except KeyboardInterrupt:
        return 130
    if reference_ms is None:
        print("bench: the calibration timed no host speed; nothing to normalise from")
        return 1
    calibrated_hz = calibrated_rate(out)
    print(f"bench: robot {quota:g} cores, found at {reference_ms:.1f} ms of workload"
          + (f", AMCL {calibrated_hz:.2f} Hz there" if math.isfinite(calibrated_hz) else ""),
          flush=True)
    if not math.isfinite(calibrated_hz):
        calibrated_hz = 2.15     # a given quota: judged against the middle of the premise
    runs = []
    try:
        for k, (round_, condition) in enumerate(order, 1):
            run_dir = os.path.join(out, f"{k:02d}-round{round_}-{condition}")
            began = time.monotonic()
            run_logged(run_argv(condition, quota, reference_ms, args.duration, run_dir), run_dir)
            runs.append(home_run(round_, condition, latest_record(run_dir)))
            print(f"[{k}/{len(order)}] {time.monotonic() - began:.0f} s: {run_line(runs[-1])}",
                  flush=True)
    except KeyboardInterrupt:
        print("bench: interrupted; the summary has the runs that ended", flush=True)
    lines = summary_lines(runs, calibrated_hz)
    print("\n".join(lines), flush=True)
    with open(os.path.join(out, "host_speed.md"), "w") as f:
        f.write("# Host speed: quotas fixed against normalised\n\n"
                + "".join(f"- {run_line(r)}\n" for r in runs) + "\n"
                + "".join(f"- {line}\n" for line in lines) + calibration_markdown(out))
    print(f"bench: {out}/host_speed.md", flush=True)
    return 0


def calibrated_rate(out: str) -> float:
    """AMCL's rate in the calibration run that measured the quota kept (NaN: given, or the
    calibration's last step was not measured)."""
    saved = read_calibration(os.path.join(out, "calibration", CALIBRATION_FILE))
    if saved is None:
        return math.nan
    quota, points, _ = saved
    return points[-1].amcl_hz if points and points[-1].quota == quota else math.nan


if __name__ == "__main__":
    sys.exit(main())
