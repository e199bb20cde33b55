"""`anyscale simulate`: runs the Fig. 7 study, prints its table beside the paper's figures and
writes a CSV and a Fig. 7-style chart. cli_simulate.py calls add_arguments() and main()."""
import csv
import os
import re
import sys
from typing import Dict, List, Sequence, Tuple

import numpy as np

from anyscale_core.allocators import ALLOCATORS

from . import simulation as sim

EXIT_USAGE = 2
# The paper's own figures (section V): Fig. 7's test-bed configuration, the mean over Fig. 7,
# and the best case.
PAPER_TESTBED = ("6Nx2Mx2K", 0.28)
PAPER_MEAN, PAPER_BEST = 0.39, 0.50
_CONFIG = re.compile(r"^(\d+)N?x(\d+)M?x(\d+)K?$", re.IGNORECASE)


class UsageError(ValueError):
    """A bad command-line value: printed as one line, exit status 2."""


def add_arguments(parser):
    """The options of `anyscale simulate`."""
    default_configs = ",".join(sim.config_label(*c) for c in sim.FIG7_CONFIGS)
    parser.add_argument("--runs", default="3", metavar="N",
                        help="seeded runs per configuration (default: 3, as in the paper)")
    parser.add_argument("--seed", default=str(sim.DEFAULT_SEED), metavar="S",
                        help=f"base seed; run r of NxMxK uses seed (S, N, M, K, r) "
                             f"(default: {sim.DEFAULT_SEED})")
    parser.add_argument("--configs", default=default_configs, metavar="LIST",
                        help="comma-separated NxMxK (or 6Nx2Mx2K) configurations "
                             "(default: Fig. 7's twelve)")
    parser.add_argument("--allocators", default="paper,optimal", metavar="LIST",
                        help=f"comma-separated allocators from: {', '.join(sorted(ALLOCATORS))} "
                             f"(default: paper,optimal)")
    parser.add_argument("--hysteresis", default=str(sim.HYSTERESIS_S), metavar="SECONDS",
                        help=f"the paper's T for the heuristics (default: {sim.HYSTERESIS_S:g}; "
                             f"the optimum always runs with T = 0, as a bound)")
    parser.add_argument("--out", default=os.path.join(".", "results", "fig7"), metavar="DIR",
                        help="where fig7.csv, fig7_runs.csv and fig7.png go "
                             "(default: ./results/fig7)")
    parser.add_argument("--no-plot", action="store_true", help="do not draw fig7.png")
    parser.add_argument("--no-progress", action="store_true",
                        help="no progress bar on stderr")


def main(args) -> int:
    try:
        options = _validated(args)
    except UsageError as e:
        print(f"anyscale simulate: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    configs, runs, seed, allocators, hysteresis = options
    try:
        os.makedirs(args.out, exist_ok=True)
    except OSError as e:
        print(f"anyscale simulate: error: cannot create --out {args.out}: {e.strerror}",
              file=sys.stderr)
        return EXIT_USAGE
    rows = _run_with_progress(configs, runs, seed, allocators, hysteresis,
                              not args.no_progress)
    summary = summarise(rows)
    print(format_table(summary, allocators))
    written = [write_csv(os.path.join(args.out, "fig7.csv"), summary),
               write_csv(os.path.join(args.out, "fig7_runs.csv"), rows)]
    if not args.no_plot:
        written.append(plot_fig7(os.path.join(args.out, "fig7.png"), summary, allocators, runs))
    for path in written:
        print(f"wrote {path}")
    return 0


def _validated(args) -> Tuple[List[Tuple[int, int, int]], int, int, List[str], float]:
    runs = _integer(args.runs, "--runs", minimum=1)
    seed = _integer(args.seed, "--seed", minimum=0)
    configs = [parse_config(c) for c in args.configs.split(",") if c.strip()]
    if not configs:
        raise UsageError("--configs: expected at least one NxMxK")
    allocators = [a.strip() for a in args.allocators.split(",") if a.strip()]
    unknown = [a for a in allocators if a not in ALLOCATORS]
    if unknown or not allocators:
        raise UsageError(f"--allocators: unknown {', '.join(unknown) or '(none given)'} "
                         f"(known: {', '.join(sorted(ALLOCATORS))})")
    try:
        hysteresis = float(args.hysteresis)
    except ValueError:
        hysteresis = -1.0
    if not hysteresis >= 0:
        raise UsageError(f"--hysteresis: expected seconds >= 0, got {args.hysteresis!r}")
    return configs, runs, seed, allocators, hysteresis


def _integer(text: str, option: str, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise UsageError(f"{option}: expected an integer, got {text!r}") from None
    if value < minimum:
        raise UsageError(f"{option}: expected an integer >= {minimum}, got {value}")
    return value


def parse_config(text: str) -> Tuple[int, int, int]:
    """'6x2x2' or '6Nx2Mx2K' -> (6, 2, 2)."""
    match = _CONFIG.match(text.strip())
    if not match:
        raise UsageError(f"--configs: expected NxMxK such as 6x2x2 or 6Nx2Mx2K, got {text!r}")
    n, m, k = (int(g) for g in match.groups())
    if k < 1 or n < 1 or not 0 <= m < n:
        raise UsageError(f"--configs: {text!r}: need N >= 1, 0 <= M < N (navigation is "
                         f"critical) and K >= 1")
    return n, m, k


def _run_with_progress(configs, runs, seed, allocators, hysteresis, show) -> List[Dict]:
    if not show:
        return sim.run_study(configs, runs, seed, allocators, hysteresis_s=hysteresis)
    from tqdm import tqdm   # only this command needs it
    with tqdm(total=len(configs) * runs, file=sys.stderr, unit="run",
              desc="Fig. 7 study") as bar:
        def progress(done, total, label):
            bar.set_postfix_str(label)
            bar.update(done - bar.n)
        return sim.run_study(configs, runs, seed, allocators, progress, hysteresis)


def summarise(rows: List[Dict]) -> List[Dict]:
    """Per configuration (in first-seen order): the mean of every numeric column over its runs."""
    groups: Dict[str, List[Dict]] = {}
    for row in rows:
        groups.setdefault(row["config"], []).append(row)
    summary = []
    for label, group in groups.items():
        mean = {key: float(np.mean([r[key] for r in group])) for key, value in group[0].items()
                if isinstance(value, (int, float)) and key not in ("run", "seed")}
        for key in ("n_nodes", "n_migratable", "n_scales"):
            mean[key] = group[0][key]
        summary.append({"config": label, "runs": len(group), **mean})
    return summary


def _pct(value: float) -> str:
    return f"{100 * value:5.1f}"


def format_table(summary: List[Dict], allocators: Sequence[str]) -> str:
    """Improvement over no migration per configuration (mean of its runs), then the means over
    all configurations, each beside the paper's figure where it gives one."""
    heads = [f"{a} %" for a in allocators] + [f"best {a} %" for a in allocators]
    width = max(len(h) for h in heads) + 2

    def cell(values):
        return "".join(f"{_pct(v):>{width}}" for v in values)

    lines = ["Improvement over no migration (1 - T_run / T_no_migration), mean of "
             f"{summary[0]['runs'] if summary else 0} runs per configuration",
             f"{'configuration':<14}{'coverage %':>11}" + "".join(f"{h:>{width}}" for h in heads)
             + f"{'published %':>12}"]
    for row in summary:
        paper = f"{100 * PAPER_TESTBED[1]:.0f}" if row["config"] == PAPER_TESTBED[0] else "-"
        lines.append(f"{row['config']:<14}{_pct(row['coverage']):>11}"
                     + cell([row[f"improvement_{a}"] for a in allocators]
                            + [row[f"best_improvement_{a}"] for a in allocators]) + f"{paper:>12}")
    if summary:
        def mean(key):
            return sum(r[key] for r in summary) / len(summary)
        lines.append(f"{'mean':<14}{_pct(mean('coverage')):>11}"
                     + cell([mean(f"improvement_{a}") for a in allocators]
                            + [mean(f"best_improvement_{a}") for a in allocators])
                     + f"{100 * PAPER_MEAN:>12.0f}")
        lines.append(f"paper (section V): {100 * PAPER_TESTBED[1]:.0f} % for "
                     f"{PAPER_TESTBED[0]}, {100 * PAPER_MEAN:.0f} % mean, "
                     f"{100 * PAPER_BEST:.0f} % best case")
    return "\n".join(lines)


def write_csv(path: str, rows: List[Dict]) -> str:
    fields = list(rows[0]) if rows else []
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    return path


def plot_fig7(path: str, summary: List[Dict], allocators: Sequence[str], runs: int) -> str:
    """Grouped bars per configuration, as in Fig. 7: each allocator with the measured coverage
    and in the best case, with the paper's figures as reference lines."""
    import matplotlib
    matplotlib.use("Agg")      # files only, no display
    import matplotlib.pyplot as plt

    labels = [r["config"] for r in summary]
    series = [(f"{a}", [r[f"improvement_{a}"] for r in summary]) for a in allocators] + \
             [(f"{a}, best case", [r[f"best_improvement_{a}"] for r in summary])
              for a in allocators]
    x = np.arange(len(labels))
    width = 0.8 / len(series)
    fig, ax = plt.subplots(figsize=(max(4.0, 0.9 * len(labels) + 1), 4.5))
    for j, (name, values) in enumerate(series):
        ax.bar(x - 0.4 + width * (j + 0.5), [100 * v for v in values], width, label=name)
    ax.axhline(100 * PAPER_MEAN, color="grey", linestyle="--", linewidth=1,
               label=f"published: mean {100 * PAPER_MEAN:.0f} %")
    ax.axhline(100 * PAPER_BEST, color="black", linestyle=":", linewidth=1,
               label=f"published: best case {100 * PAPER_BEST:.0f} %")
    if PAPER_TESTBED[0] in labels:
        ax.plot([labels.index(PAPER_TESTBED[0])], [100 * PAPER_TESTBED[1]], "k*", markersize=10,
                label=f"published: {PAPER_TESTBED[0]} {100 * PAPER_TESTBED[1]:.0f} %")
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("performance improvement (%)")
    ax.set_ylim(0, 60)
    ax.set_title(f"Fig. 7 simulation (N nodes, M migratable, K scales; mean of {runs} runs)",
                 fontsize=10)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))   # beside the bars
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path
