#!/usr/bin/python3
"""The three-scale bench (root, issue 39): the office loop on two scales (robot, laptop) and on
three (robot, laptop, server behind the access point), the same seed and robot quota, one run
each, side by side: path time, migrations, violations, each output's longest silence against
its Δ, and how long each node that may move ran on each scale. Each run is
scripts/run_testbed.py; a run already recorded in --out is not run again. A pair takes about
16 minutes on the office floor and needs the machine to itself. Run with the workspace sourced:
    sudo -E /usr/bin/python3 tests/bench/bench_three_scales.py --seed 1
"""
import argparse
import os
import sys

try:
    from anyscale_testbed.bench_runs import latest_record, run_logged, save_table, \
        start_on_the_testbed
    from anyscale_testbed.scale_times import seconds, time_per_scale
    from anyscale_testbed.tolerance_report import run_row, silence_cell
except ImportError as e:
    sys.exit(f"{os.path.basename(__file__)}: {e}: source this workspace first "
             "(source devel/setup.bash; scripts/setup.sh installs and builds it)")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RUN_TESTBED = os.path.join(ROOT, "scripts", "run_testbed.py")
SCALE_SETS = ("robot,laptop", "robot,laptop,server")
SCALES = SCALE_SETS[-1].split(",")


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--world", default="office_floor", help="office_floor (default), small_loop")
    p.add_argument("--seed", type=int, default=1,
                   help="the WiFi variation's seed, the same for both runs (default 1)")
    p.add_argument("--robot-cpu", default="",
                   help="robot CPU quota in cores for both runs (default: the calibration "
                        "file's)")
    p.add_argument("--out", default=os.path.join(ROOT, "results", "three_scales"),
                   help="directory of the runs and of three_scales.md")
    return p.parse_args(argv)


def run_dir(out: str, scales: str) -> str:
    return os.path.join(out, f"{len(scales.split(','))}-scales")


def table(rows) -> str:
    """The two runs side by side, markdown: a column per run."""
    (two, rec2), (three, rec3) = rows
    topics = sorted(set(two.tolerances) | set(three.tolerances))
    times = [time_per_scale(r, r.finished_t or 0.0) if r is not None else {}
             for r in (rec2, rec3)]
    lines = ["| | " + " | ".join(SCALE_SETS) + " |", "|---|---|---|"]

    def line(label, cells):
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    line("exit", [str(r.exit_code) for r in (two, three)])
    line("path time", [f"{r.path_time_s:.0f} s" if r.path_time_s == r.path_time_s else "-"
                       for r in (two, three)])
    line("migrations", [str(r.migrations) for r in (two, three)])
    line("violations", [str(len(r.violations)) for r in (two, three)])
    for topic in topics:
        line(f"{topic} longest/Δ",
             [silence_cell(r, topic) if topic in r.tolerances else "-" for r in (two, three)])
    moving = sorted({n for t in times for n, per in t.items() if set(per) - {"robot"}})
    for node in moving:
        line(f"{node}: robot / laptop / server",
             [" / ".join(seconds(t.get(node, {}).get(s, 0.0)) for s in SCALES) for t in times])
    for row, _ in rows:
        if row.note:
            lines.append(f"\n{row.note}")
    return "\n".join(lines)


def main(argv=None) -> int:
    args = parse_args(argv)
    start_on_the_testbed("bench_three_scales")
    rows = []
    for k, scales in enumerate(SCALE_SETS, 1):
        out = run_dir(args.out, scales)
        rec = latest_record(out)
        code = 0
        if rec is None:
            print(f"[{k}/{len(SCALE_SETS)}] --scales {scales}, seed {args.seed} ...", flush=True)
            argv = [sys.executable, RUN_TESTBED, "--world", args.world, "--seed",
                    str(args.seed), "--scales", scales, "--out", out]
            if args.robot_cpu:
                argv += ["--robot-cpu", args.robot_cpu]
            code = run_logged(argv, out)
            rec = latest_record(out)
        else:
            print(f"[{k}/{len(SCALE_SETS)}] --scales {scales}: recorded already in {out}")
        rows.append((run_row(k, 0, code, rec, args.seed), rec))
    save_table(f"# Two scales against three ({args.world}, seed {args.seed})\n\n" + table(rows),
               args.out, "three_scales.md")
    return 0 if all(r.exit_code == 0 and not r.violations for r, _ in rows) else 1


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        sys.exit(130)
