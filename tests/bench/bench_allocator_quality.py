#!/usr/bin/python3
"""Benchmark: how far each heuristic allocator's decision falls below the exact optimum (Eq. 1),
on the Fig. 7 configurations and on seeded random instances. Prints figures; asserts nothing."""
import argparse
import os
import sys
import time

import numpy as np

SRC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "src")
sys.path[:0] = [os.path.join(SRC, pkg, "src") for pkg in ("anyscale_core", "anyscale_study")]
from anyscale_core.allocators import (ALLOCATORS, BUDGETED, DEFAULT_TIME_BUDGET_S,  # noqa: E402
                                      AllocationContext, make_allocator)
from anyscale_core.characterisation import characterise            # noqa: E402
from anyscale_core.constraints import DynamicState, is_feasible    # noqa: E402
from anyscale_core.cost import perf                                 # noqa: E402
from anyscale_study import simulation as sim                        # noqa: E402


def random_state(ch, rng) -> DynamicState:
    """Bandwidth: an 802.11g rate step x TCP efficiency, or 0; each remote scale busy with 0-90 %
    background load and its link up with probability 0.8."""
    steps = [0.0] + [r * sim.TCP_EFFICIENCY for r in sim.RATE_STEPS_MBPS]
    remote = [s for i, s in enumerate(ch.scale_names) if i != ch.master]
    return DynamicState(float(rng.choice(steps)),
                        scale_load={s: float(rng.uniform(0, 90)) for s in remote},
                        link_up={s: bool(rng.random() < 0.8) for s in remote})


def random_instance(rng):
    """N in 3..18, M in 1..N-1, K in 2..5, a generated Fig. 3-like system and a random state."""
    n = int(rng.integers(3, 19))
    m = int(rng.integers(1, n))
    k = int(rng.integers(2, 6))
    ch = characterise(sim.generate_model(n, m, k, rng))
    return (n, m, k), ch, random_state(ch, rng)


def gaps(ch, state, heuristics, optimal):
    """Per heuristic: (1 - Perf_h / Perf_opt, 1 - gain_h / gain_opt) from the all-on-master start,
    or None when its decision is infeasible (the gain is Perf above all-on-master)."""
    start = ch.initial_mapping()
    base = perf(ch, start)
    best = perf(ch, optimal.decide(ch, start, state, AllocationContext()).assign)
    out = {}
    for name, alloc in heuristics.items():
        assign = alloc.decide(ch, start, state, AllocationContext()).assign
        if not is_feasible(ch, assign, state):
            out[name] = None
            continue
        value = perf(ch, assign)
        gain_gap = 1 - (value - base) / (best - base) if best - base > 1e-9 else 0.0
        out[name] = (1 - value / best, gain_gap)
    return out


class Tally:
    def __init__(self):
        self.perf, self.gain, self.infeasible = [], [], 0

    def add(self, result):
        if result is None:
            self.infeasible += 1
        else:
            self.perf.append(result[0])
            self.gain.append(result[1])

    def line(self, label, name):
        p, g = np.array(self.perf), np.array(self.gain)
        if not len(p):
            return f"{label:<22}{name:<12} no feasible decisions"
        return (f"{label:<22}{name:<12}{len(p):>6}{100 * p.mean():>9.2f}{100 * p.max():>9.2f}"
                f"{100 * g.mean():>10.2f}{100 * g.max():>9.2f}{100 * np.mean(p < 1e-4):>9.1f}"
                f"{self.infeasible:>6}")


HEADER = (f"{'instances':<22}{'alloc':<12}{'n':>6}{'mean %':>9}{'worst %':>9}"
          f"{'gain m %':>10}{'gain w %':>9}{'=opt %':>9}{'infeas':>6}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0] + " Gap = 1 - Perf_h / "
                                     "Perf_opt (Eq. 1, all nodes); gain gap = the same on Perf "
                                     "above the all-on-master mapping.")
    parser.add_argument("--instances", type=int, default=1000,
                        help="random instances (default 1000)")
    parser.add_argument("--per-config", type=int, default=30,
                        help="systems x states per Fig. 7 configuration (default 30)")
    parser.add_argument("--seed", type=int, default=1, help="base seed (default 1)")
    parser.add_argument("--allocators", default=",".join(a for a in ALLOCATORS
                                                         if a != "optimal"),
                        help="heuristics to compare with the optimum (default: all registered)")
    parser.add_argument("--time-budget-s", type=lambda t: None if t == "none" else float(t),
                        default=DEFAULT_TIME_BUDGET_S,
                        help=f"budget of the heuristics that search ({', '.join(BUDGETED)}) "
                             f"per decision, s, or 'none' (default {DEFAULT_TIME_BUDGET_S:g}, the "
                             f"decision node's); the optimum has none")
    args = parser.parse_args(argv)
    names = [a for a in args.allocators.split(",") if a]
    unknown = [a for a in names if a not in ALLOCATORS or a == "optimal"]
    if unknown:
        parser.error(f"unknown heuristic allocator(s): {', '.join(unknown)}")
    from tqdm import tqdm
    heuristics = {a: make_allocator(a, args.time_budget_s) for a in names}
    optimal = make_allocator("optimal", time_budget_s=None)
    started = time.time()
    per_config = {}
    with tqdm(total=len(sim.FIG7_CONFIGS) * args.per_config + args.instances, file=sys.stderr,
              unit="inst", desc="allocator quality") as bar:
        for cfg in sim.FIG7_CONFIGS:
            tallies = per_config.setdefault(cfg, {a: Tally() for a in names})
            for j in range(args.per_config):
                rng = np.random.default_rng([args.seed, *cfg, j])
                ch = characterise(sim.generate_model(*cfg, rng))
                # Half at full usable bandwidth with idle scales (the Fig. 7 ideal), half random.
                state = DynamicState(sim.FULL_USABLE_MBPS) if j % 2 == 0 else random_state(ch, rng)
                for name, result in gaps(ch, state, heuristics, optimal).items():
                    tallies[name].add(result)
                bar.update()
        overall = {a: Tally() for a in names}
        for j in range(args.instances):
            rng = np.random.default_rng([args.seed, 999, j])
            _, ch, state = random_instance(rng)
            for name, result in gaps(ch, state, heuristics, optimal).items():
                overall[name].add(result)
            bar.update()
    budget = "none" if args.time_budget_s is None else f"{1000 * args.time_budget_s:g} ms"
    print(f"Heuristic vs exact optimum, decisions from all-on-master (seed {args.seed}, time "
          f"budget {budget}); the paper claims a 10-15 % mean deviation")
    print(HEADER)
    for cfg, tallies in per_config.items():
        for name, tally in tallies.items():
            print(tally.line(sim.config_label(*cfg), name))
    for name, tally in overall.items():
        print(tally.line(f"random x{args.instances}", name))
    print(f"({time.time() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
