#!/usr/bin/python3
"""Benchmark: time per allocation decision at N=18 M=9 K=5 and N=200 M=100 K=20 (median and p95
over repeated decisions on seeded systems and states), and how far each decision's Perf (Eq. 1)
falls below the best any of them found on the same case. Prints figures; asserts nothing."""
import argparse
import os
import sys
import time

import numpy as np

SRC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src")
sys.path[:0] = [os.path.join(SRC, pkg, "src") for pkg in ("anyscale_core", "anyscale_study")]
from anyscale_core.allocators import (ALLOCATORS, BUDGETED, DEFAULT_ALLOCATOR,  # noqa: E402
                                      DEFAULT_TIME_BUDGET_S, AllocationContext, make_allocator)
from anyscale_core.characterisation import characterise            # noqa: E402
from anyscale_core.constraints import DynamicState                  # noqa: E402
from anyscale_core.cost import perf                                 # noqa: E402
from anyscale_study import simulation as sim                        # noqa: E402

SIZES = ((18, 9, 5), (200, 100, 20))
GOALS_MS = {18: 5.0, 200: 100.0}           # p95, for the default allocator


def cases(size, count, seed):
    """(ch, state, start) triples: half at full usable bandwidth with idle scales, half with a
    random bandwidth step, loads and links; every decision starts from all-on-master, the start
    with the most to move."""
    out = []
    for j in range(count):
        rng = np.random.default_rng([seed, *size, j])
        ch = characterise(sim.generate_model(*size, rng))
        remote = [s for i, s in enumerate(ch.scale_names) if i != ch.master]
        if j % 2 == 0:
            state = DynamicState(sim.FULL_USABLE_MBPS)
        else:
            state = DynamicState(float(rng.choice(sim.RATE_STEPS_MBPS)) * sim.TCP_EFFICIENCY,
                                 {s: float(rng.uniform(0, 90)) for s in remote},
                                 {s: bool(rng.random() < 0.8) for s in remote})
        out.append((ch, state, ch.initial_mapping()))
    return out


def jobs(names, budget):
    """(label, allocator, method) for every timed decision; paper_local also without a budget
    (the search to its end, what the budget cuts short)."""
    out = []
    for name in names:
        if name == "paper":
            out += [("paper.step", make_allocator(name), "step"),
                    ("paper.decide", make_allocator(name), "decide")]
        else:
            out.append((f"{name}.decide", make_allocator(name, budget), "decide"))
        if name == "paper_local" and budget is not None:
            out.append(("paper_local.decide (no budget)", make_allocator(name, None), "decide"))
    return out


def parse_budget(text):
    return None if text == "none" else float(text)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0] + " `step` is one "
                                     "iteration of Algorithm 1 (one decision period of the "
                                     "paper's loop); `decide` converges.")
    parser.add_argument("--systems", type=int, default=10,
                        help="seeded systems x states per size (default 10)")
    parser.add_argument("--repeats", type=int, default=5,
                        help="timed decisions per system and allocator (default 5)")
    parser.add_argument("--seed", type=int, default=1, help="base seed (default 1)")
    parser.add_argument("--allocators", default=",".join(ALLOCATORS),
                        help="allocators to time (default: all registered)")
    parser.add_argument("--reference-s", type=float, default=0.0,
                        help="also count, in the best Perf of each case, `optimal` given this "
                             "many seconds (untimed; default 0: off). At N=200 the decisions "
                             "timed here are not the optimum, and their gap to each other "
                             "hides that")
    parser.add_argument("--time-budget-s", type=parse_budget, default=DEFAULT_TIME_BUDGET_S,
                        help=f"budget of {' and '.join(BUDGETED)} per decision, s, or 'none' "
                             f"(default {DEFAULT_TIME_BUDGET_S:g}, the decision node's)")
    args = parser.parse_args(argv)
    names = [a for a in args.allocators.split(",") if a]
    unknown = [a for a in names if a not in ALLOCATORS]
    if unknown:
        parser.error(f"unknown allocator(s): {', '.join(unknown)}")
    from tqdm import tqdm
    timed = jobs(names, args.time_budget_s)
    reference = make_allocator("optimal", args.reference_s) if args.reference_s > 0 else None
    times, gaps = {}, {}          # (size, label) -> ms per decision; 1 - Perf / best Perf
    with tqdm(total=len(SIZES) * args.systems, file=sys.stderr, unit="sys",
              desc="decision time") as bar:
        for size in SIZES:
            for ch, state, start in cases(size, args.systems, args.seed):
                perfs = {}
                for label, alloc, method in timed:
                    call = getattr(alloc, method)
                    call(ch, start, state, AllocationContext())     # warm caches, untimed
                    for _ in range(args.repeats):
                        t = time.perf_counter()
                        d = call(ch, start, state, AllocationContext())
                        times.setdefault((size, label), []).append(
                            1000 * (time.perf_counter() - t))
                        perfs.setdefault(label, []).append(perf(ch, d.assign))
                best = max(max(p) for p in perfs.values())
                if reference is not None:
                    best = max(best, perf(ch, reference.decide(ch, start, state,
                                                               AllocationContext()).assign))
                for label, p in perfs.items():
                    if not label.endswith(".step"):     # one move of many: no decision
                        gaps.setdefault((size, label), []).extend(1 - np.array(p) / best)
                bar.update()
    budget = "none" if args.time_budget_s is None else f"{1000 * args.time_budget_s:g} ms"
    print(f"Decision time per allocator (ms; {args.systems} seeded systems x states per size, "
          f"{args.repeats} decisions each, from all-on-master; time budget {budget}). Goal for "
          f"the default allocator `{DEFAULT_ALLOCATOR}`: p95 <= "
          f"{' and '.join(f'{g:g} ms at N={n}' for n, g in GOALS_MS.items())}. gap = 1 - Perf "
          f"/ the best Perf any decision reached on the same case"
          + (f" (with `optimal` given {args.reference_s:g} s)" if reference else "")
          + ", mean and worst, %")
    width = 38
    print(f"{'allocator':<32}" + "".join(f"{f'N={s[0]} M={s[1]} K={s[2]}':>{width}}"
                                         for s in SIZES))
    print(f"{'':<32}" + "".join(f"{'median':>9}{'p95':>9}{'gap':>7}{'worst':>7}{'n':>6}"
                                for _ in SIZES))
    labels = [label for label, _, _ in timed]
    for label in sorted(labels, key=lambda x: (x.split(".")[0] != DEFAULT_ALLOCATOR,
                                               labels.index(x))):
        cells = ""
        for size in SIZES:
            t = np.array(times.get((size, label), []))
            g = 100 * np.array(gaps.get((size, label), []))
            gap = f"{g.mean():>7.2f}{g.max():>7.2f}" if len(g) else f"{'-':>7}{'-':>7}"
            cells += (f"{np.median(t):>9.2f}{np.percentile(t, 95):>9.2f}{gap}{len(t):>6}"
                      if len(t) else f"{'-':>{width}}")
        print(f"{label:<32}{cells}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
