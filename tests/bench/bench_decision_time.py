#!/usr/bin/python3
"""Benchmark: time per allocation decision at N=18 M=9 K=5 and N=200 M=100 K=20 (median and p95
over repeated decisions on seeded systems and states). Prints figures; asserts nothing."""
import argparse
import os
import sys
import time

import numpy as np

SRC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src")
sys.path[:0] = [os.path.join(SRC, pkg, "src") for pkg in ("anyscale_core", "anyscale_study")]
from anyscale_core.allocators import ALLOCATORS, AllocationContext, make_allocator  # noqa: E402
from anyscale_core.characterisation import characterise            # noqa: E402
from anyscale_core.constraints import DynamicState                  # noqa: E402
from anyscale_study import simulation as sim                        # noqa: E402

SIZES = ((18, 9, 5), (200, 100, 20))
GOALS_MS = {18: 5.0, 200: 100.0}           # for the default allocator (paper)


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


def timed(call, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        call()
        times.append(1000 * (time.perf_counter() - t))
    return times


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0] + " `step` is one "
                                     "iteration of Algorithm 1 (one decision period of the "
                                     "paper's loop); `decide` converges.")
    parser.add_argument("--systems", type=int, default=10,
                        help="seeded systems x states per size (default 10)")
    parser.add_argument("--repeats", type=int, default=5,
                        help="timed decisions per system and allocator (default 5)")
    parser.add_argument("--optimal-repeats", type=int, default=1,
                        help="timed optimal decisions per system at N=200 (default 1: each "
                             "can take its 2 s MILP time limit)")
    parser.add_argument("--seed", type=int, default=1, help="base seed (default 1)")
    parser.add_argument("--allocators", default=",".join(ALLOCATORS),
                        help="allocators to time (default: all registered)")
    args = parser.parse_args(argv)
    names = [a for a in args.allocators.split(",") if a]
    unknown = [a for a in names if a not in ALLOCATORS]
    if unknown:
        parser.error(f"unknown allocator(s): {', '.join(unknown)}")
    from tqdm import tqdm
    # (label, size) -> list of ms
    results = {}
    jobs = [(size, name, mode) for size in SIZES for name in names
            for mode in (("step", "decide") if name == "paper" else ("decide",))]
    with tqdm(total=len(jobs) * args.systems, file=sys.stderr, unit="sys",
              desc="decision time") as bar:
        for size, name, mode in jobs:
            alloc = make_allocator(name)
            repeats = args.optimal_repeats if name == "optimal" and size[0] > 50 \
                else args.repeats
            times = results.setdefault((size, f"{name}.{mode}"), [])
            for ch, state, start in cases(size, args.systems, args.seed):
                call = getattr(alloc, mode)
                alloc_call = (lambda c=call, ch=ch, st=state, a=start:
                              c(ch, a, st, AllocationContext()))
                alloc_call()                    # warm caches outside the timing
                times.extend(timed(alloc_call, repeats))
                bar.update()
    print(f"Decision time per allocator (ms; {args.systems} seeded systems x states per size; "
          f"goal for the default allocator `paper`: <= 5 ms at N=18, <= 100 ms at N=200)")
    labels = sorted({label for _, label in results}, key=lambda x: (x.split(".")[0] != "paper",
                                                                   x))
    print(f"{'allocator':<22}" + "".join(f"{f'N={s[0]} M={s[1]} K={s[2]}':>30}" for s in SIZES))
    print(f"{'':<22}" + "".join(f"{'median':>10}{'p95':>10}{'n':>10}" for _ in SIZES))
    for label in labels:
        cells = ""
        for size in SIZES:
            t = np.array(results.get((size, label), []))
            cells += (f"{np.median(t):>10.2f}{np.percentile(t, 95):>10.2f}{len(t):>10}"
                      if len(t) else f"{'-':>30}")
        print(f"{label:<22}{cells}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
