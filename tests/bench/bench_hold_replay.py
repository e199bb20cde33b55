#!/usr/bin/python3
"""The hold after a link loss, weighed on recorded links (no root, no test bed): each
office-floor coverage run recorded under the given directories (record.json, the link the run
met) is replayed under several holds for one node (anyscale_testbed/hold_replay.py), side by
side, and the bench prints per hold: the share of the time the link carried the node that it
would have spent out, the moves out and those a loss ended within 10 s (link-loss returns on a
flickering link), per run and as ratios against the 20 s hold of the evaluation of 2026-11-27.

    /usr/bin/python3 tests/bench/bench_hold_replay.py /work/results/eval_s28 /work/results/tol_s28

The robot's position is the record's: a node out longer would have driven the robot faster
through the coverage, which the replay does not model. What a return costs in Δ is not here
either: that is the runs' own move table (bench_tolerances.py, the main job's end table).
"""
import argparse
import glob
import os
import sys

try:
    from anyscale_testbed.hold_replay import ReplayRules, doubling_hold, fixed_hold, replay_hold
    from anyscale_testbed.testbed_record import TestbedRecord
except ImportError as e:
    sys.exit(f"bench_hold_replay.py: {e}: source this workspace first (source devel/setup.bash)")

POLICIES = {
    "none (bandwidth hold only)": fixed_hold(0.0),
    "10 s": fixed_hold(10.0),
    "20 s": fixed_hold(20.0),
    "30 s": fixed_hold(30.0),
    "5 s doubling per loss in 60 s, <= 20 s": doubling_hold(5.0, 60.0, 20.0),
    "5 s doubling per loss in 60 s, <= 40 s": doubling_hold(5.0, 60.0, 40.0),
    "5 s doubling per loss in 120 s, <= 40 s": doubling_hold(5.0, 120.0, 40.0),
}
REFERENCE = "20 s"


def coverage_records(dirs):
    """Records of the runs under `dirs` that met the coverage link, each once."""
    found = {}
    for d in dirs:
        for path in glob.glob(os.path.join(d, "**", "record.json"), recursive=True):
            rec = TestbedRecord.load(path)
            if rec.link == "coverage" and len(rec.bandwidth) > 1:
                found[os.path.realpath(path)] = rec
    return found


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("dirs", nargs="+", help="directories searched for record.json")
    p.add_argument("--weak-link", type=float, default=ReplayRules.weak_link_mbps,
                   help="Mbit/s below which the link carries nothing (robot.launch: 5.5)")
    args = p.parse_args()
    records = coverage_records(args.dirs)
    if not records:
        print(f"bench_hold_replay.py: no coverage-link record.json under {', '.join(args.dirs)}",
              file=sys.stderr)
        return 2
    rules = ReplayRules(weak_link_mbps=args.weak_link)
    totals = {}
    for name, policy in POLICIES.items():
        results = [replay_hold(rec.bandwidth, policy, rules) for rec in records.values()]
        # summed over the runs: the shares weigh each run by the time its link carried the node
        totals[name] = (sum(r.carried_s for r in results), sum(r.out_s for r in results),
                        sum(r.moves_out for r in results), sum(r.ended_soon for r in results))
    runs = len(records)
    ref_out, ref_soon = totals[REFERENCE][1], totals[REFERENCE][3]
    print(f"{runs} runs on the coverage link, {totals[REFERENCE][0]:.0f} s carried in all")
    print(f"{'hold after a loss':42s} {'out':>6s} {'x 20 s':>7s} {'moves/run':>10s} "
          f"{'ended <10 s/run':>16s} {'x 20 s':>7s}")
    for name, (carried, out, moves, soon) in totals.items():
        print(f"{name:42s} {100 * out / carried:5.1f}% {out / ref_out:7.2f} {moves / runs:10.1f} "
              f"{soon / runs:16.1f} {soon / ref_soon if ref_soon else float('nan'):7.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
