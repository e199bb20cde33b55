"""The evaluation's table (scripts/run_evaluation.py): one row per run and a mean row per
allocator over its seeded tests, against the baseline (every node on the robot), beside the
paper's figures (section V, Fig. 6); aligned text, Markdown and CSV. Pure (no ROS): it lays
out evaluation_figures.RunFigures.

Two baselines: the mean of every baseline run, and for a test run in an interleaved pair its
own paired baseline, the baseline run measured just before it. This machine is a shared VM
whose speed drifts over hours and days (baselines of different days took 361-583 s), so only
the paired gain compares runs measured side by side. Each run also shows AMCL's rate with every
node home and is flagged where that is off the premise (premise_figures.py)."""
import csv
import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence

import numpy as np

from .evaluation_figures import CONFIGURATIONS, RunFigures, own_speed_share
from .evaluation_shortfall import CAUSES
from .premise_figures import premise_is_off, premise_off_note
from .tolerance_report import silence_cell, topics_of

# The paper's figures (section V): over its four tests, migration cut the time to complete by
# 28 % against no migration, with the network everywhere by 50 %; the mean angular velocity
# was about 5 % above the baseline's, and 4 deg/s is the limit of safe behaviour.
PAPER_MEAN_GAIN = 0.28
PAPER_BEST_CASE_GAIN = 0.50
PAPER_OMEGA_ABOVE_BASELINE = 0.05
SAFE_OMEGA_DEG_S = 4.0

KIND_TITLES = {"paper": "AnyScale (paper)", "paper_local": "AnyScale (paper_local)",
               "optimal": "AnyScale (optimal)"}


@dataclass(frozen=True)
class Baseline:
    """What the gains are measured against: the mean of the baseline runs that completed. One
    run is not enough: on the starved robot AMCL's rate, and with it the robot's speed, varies
    from run to run (the baseline's time to complete varied by 15 % between two runs)."""
    path_time_s: float
    mean_omega_deg_s: float
    turning_deg_per_m: float
    runs: int
    shortest_s: float
    longest_s: float


def baseline_of(figures: Sequence[RunFigures]) -> Optional[Baseline]:
    runs = [f for f in figures if f.kind == "baseline" and math.isfinite(f.row.path_time_s)]
    if not runs:
        return None
    times = [f.row.path_time_s for f in runs]
    return Baseline(float(np.mean(times)), _nanmean([f.mean_omega_deg_s for f in runs]),
                    _nanmean([f.turning_deg_per_m for f in runs]),
                    len(runs), min(times), max(times))


def _ratio(value: float, reference: Optional[float]) -> float:
    if reference is None or not math.isfinite(value) or not reference or \
            not math.isfinite(reference):
        return math.nan
    return value / reference


def gain(f: RunFigures, baseline: Optional[Baseline]) -> float:
    """1 - time to complete / the baseline's (NaN where either is missing). A baseline run's
    own is its difference from the baseline runs' mean."""
    return 1.0 - _ratio(f.row.path_time_s, baseline.path_time_s if baseline else None)


def bound_gain(f: RunFigures, baseline: Optional[Baseline]) -> float:
    """The coverage bound's gain against the baseline (evaluation_figures.coverage_bound)."""
    return 1.0 - _ratio(f.bound.time_s, baseline.path_time_s if baseline else None)


def bound_share(f: RunFigures, baseline: Optional[Baseline]) -> float:
    """The share of the coverage bound's gain this run reached."""
    reachable = bound_gain(f, baseline)
    return _ratio(gain(f, baseline), reachable if reachable > 0 else None)


def paired_baseline(f: RunFigures, figures: Sequence[RunFigures]) -> Optional[Baseline]:
    """The baseline of f's pair: the baseline run of the same pair, measured just before f.
    None for a run outside a pair, for a pair's baseline itself, and where the pair's baseline
    is not recorded or did not complete."""
    if not f.pair or f.kind == "baseline":
        return None
    return baseline_of([b for b in figures if b.kind == "baseline" and b.pair == f.pair])


def paired_gain(f: RunFigures, figures: Sequence[RunFigures]) -> float:
    """1 - time to complete / its paired baseline's (NaN without one, or where f did not
    complete)."""
    return gain(f, paired_baseline(f, figures))


def paired_bound_share(f: RunFigures, figures: Sequence[RunFigures]) -> float:
    """The share of the coverage bound's gain reached, both against the paired baseline."""
    return bound_share(f, paired_baseline(f, figures))


@dataclass(frozen=True)
class Spread:
    """Mean, sample standard deviation and range of the finite values among some (NaN where
    there are too few: none, or one for the deviation)."""
    mean: float
    sd: float
    lowest: float
    highest: float
    count: int


def spread_of(values: Sequence[float]) -> Spread:
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return Spread(math.nan, math.nan, math.nan, math.nan, 0)
    return Spread(float(np.mean(finite)),
                  float(np.std(finite, ddof=1)) if len(finite) > 1 else math.nan,
                  min(finite), max(finite), len(finite))


def paired_gain_spread(tests: Sequence[RunFigures], figures: Sequence[RunFigures]) -> Spread:
    """Of the tests' paired gains (the pairs with both runs complete)."""
    return spread_of([paired_gain(f, figures) for f in tests])


def _spread_cell(s: Spread) -> str:
    if not s.count:
        return "-"
    sd = f"sd {_percent(s.sd)}, " if math.isfinite(s.sd) else ""
    return (f"{_percent(s.mean)} ({sd}{100 * s.lowest:.1f} to {100 * s.highest:.1f} %, "
            f"{s.count} pair{'s' if s.count > 1 else ''})")


def note_cell(f: RunFigures) -> str:
    """The run's note, and the premise flag where its AMCL ran off the premise at home."""
    return "; ".join(n for n in (f.row.note, premise_off_note(f.amcl_hz_home)) if n)


def _percent(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{100 * v:.1f} %"


def _fixed(v: float, unit: str, digits: int = 1) -> str:
    return "-" if not math.isfinite(v) else f"{v:.{digits}f}{unit}"


def header(topics: Sequence[str]) -> List[str]:
    return (["run", "exit", "time to complete", "gain vs baseline", "gain vs paired baseline",
             "coverage bound", "share of bound's gain at own speeds", "share of bound's gain",
             "share of bound's gain vs paired",
             "AMCL at home", "cruise at home", "mean |w|", "|w| / baseline",
             "turning per m / baseline", "markers", "AMCL RMS error"]
            + [f"{t} longest/Δ" for t in topics]
            + ["violations", "migrations"] + [f"{c} time" for c in CONFIGURATIONS] + ["note"])


def run_cells(f: RunFigures, baseline: Optional[Baseline], topics: Sequence[str],
              figures: Sequence[RunFigures] = ()) -> List[str]:
    """One run's row; `figures` (every run) holds its paired baseline."""
    base_omega = baseline.mean_omega_deg_s if baseline else None
    has_bound = f.kind not in ("baseline", "best_case")
    bound = (f"{f.bound.time_s:.0f} s ({_percent(bound_gain(f, baseline))})"
             if has_bound and math.isfinite(f.bound.time_s) else "-")
    return ([f.name, str(f.row.exit_code), _fixed(f.row.path_time_s, " s", 0),
             _percent(gain(f, baseline)), _percent(paired_gain(f, figures)), bound,
             _percent(own_speed_share(f.bound)) if has_bound else "-",
             _percent(bound_share(f, baseline)) if has_bound else "-",
             _percent(paired_bound_share(f, figures)) if has_bound else "-",
             _fixed(f.amcl_hz_home, " Hz", 2), _fixed(f.cruise_mps_home, " m/s", 2),
             _fixed(f.mean_omega_deg_s, " °/s", 2), _fixed(_ratio(f.mean_omega_deg_s, base_omega),
                                                           "", 3),
             _turning(f.turning_deg_per_m, baseline),
             str(f.markers), _fixed(f.rms_error_m, " m", 3)]
            + [silence_cell(f.row, t) for t in topics]
            + [str(len(f.row.violations)), str(f.row.migrations)]
            + [_percent(f.shares[c]) if f.shares else "-" for c in CONFIGURATIONS]
            + [note_cell(f)])


def _turning(deg_per_m: float, baseline: Optional[Baseline]) -> str:
    ratio = _ratio(deg_per_m, baseline.turning_deg_per_m if baseline else None)
    return "-" if not math.isfinite(deg_per_m) else \
        f"{deg_per_m:.2f} °/m" + (f" ({ratio:.3f})" if math.isfinite(ratio) else "")


def _nanmean(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


def mean_cells(kind: str, runs: Sequence[RunFigures], baseline: Optional[Baseline],
               topics: Sequence[str], figures: Sequence[RunFigures] = ()) -> List[str]:
    """The mean over one allocator's seeded tests (of the runs that have each figure); the
    paired gains' with their spread."""
    base_omega = baseline.mean_omega_deg_s if baseline else None
    omega = _nanmean([f.mean_omega_deg_s for f in runs])
    silences = []
    for t in topics:
        longest = [f.row.longest_s.get(t, math.nan) for f in runs]
        silences.append(_fixed(max([v for v in longest if math.isfinite(v)], default=math.nan),
                               " s max", 2))
    return ([f"mean {KIND_TITLES.get(kind, kind)}, {len(runs)} tests", "",
             _fixed(_nanmean([f.row.path_time_s for f in runs]), " s", 0),
             _percent(_nanmean([gain(f, baseline) for f in runs])),
             _spread_cell(paired_gain_spread(runs, figures)),
             f"{_fixed(_nanmean([f.bound.time_s for f in runs]), ' s', 0)} "
             f"({_percent(_nanmean([bound_gain(f, baseline) for f in runs]))})",
             _percent(_nanmean([own_speed_share(f.bound) for f in runs])),
             _percent(_nanmean([bound_share(f, baseline) for f in runs])),
             _percent(_nanmean([paired_bound_share(f, figures) for f in runs])),
             _fixed(_nanmean([f.amcl_hz_home for f in runs]), " Hz", 2),
             _fixed(_nanmean([f.cruise_mps_home for f in runs]), " m/s", 2),
             _fixed(omega, " °/s", 2), _fixed(_ratio(omega, base_omega), "", 3),
             _turning(_nanmean([f.turning_deg_per_m for f in runs]), baseline),
             _fixed(_nanmean([f.markers for f in runs]), "", 1),
             _fixed(_nanmean([f.rms_error_m for f in runs]), " m", 3)]
            + silences
            + [str(sum(len(f.row.violations) for f in runs)),
               _fixed(_nanmean([f.row.migrations for f in runs]), "", 1)]
            + [_percent(_nanmean([f.shares.get(c, math.nan) for f in runs]))
               for c in CONFIGURATIONS] + [""])


def seeded_kinds(figures: Sequence[RunFigures]) -> Dict[str, List[RunFigures]]:
    """The allocators' seeded tests, by allocator, in the order they first appear."""
    kinds: Dict[str, List[RunFigures]] = {}
    for f in figures:
        if f.kind not in ("baseline", "best_case"):
            kinds.setdefault(f.kind, []).append(f)
    return kinds


def table_lines(figures: Sequence[RunFigures]) -> List[List[str]]:
    """Header, a row per run, then a mean row per allocator."""
    topics = topics_of([f.row for f in figures])
    baseline = baseline_of(figures)
    lines = [header(topics)] + [run_cells(f, baseline, topics, figures) for f in figures]
    lines += [mean_cells(k, runs, baseline, topics, figures)
              for k, runs in seeded_kinds(figures).items()]
    return lines


def paper_comparison(figures: Sequence[RunFigures]) -> List[str]:
    """The paper's headline figures beside ours, one line each."""
    baseline = baseline_of(figures)
    tests = seeded_kinds(figures).get("paper", [])
    best = next((f for f in figures if f.kind == "best_case"), None)
    omega = _nanmean([f.mean_omega_deg_s for f in tests])
    above = _ratio(omega, baseline.mean_omega_deg_s if baseline else None) - 1.0
    turning = _ratio(_nanmean([f.turning_deg_per_m for f in tests]),
                     baseline.turning_deg_per_m if baseline else None) - 1.0
    paired = paired_gain_spread(tests, figures)
    highest = max([f.mean_omega_deg_s for f in figures
                   if f.kind in ("baseline", "paper") and math.isfinite(f.mean_omega_deg_s)],
                  default=math.nan)
    return [
        (f"baseline: {baseline.runs} runs, mean time to complete {baseline.path_time_s:.0f} s "
         f"({baseline.shortest_s:.0f}-{baseline.longest_s:.0f} s)") if baseline else
        "baseline: none recorded",
        f"mean gain of the AnyScale tests: paper {_percent(PAPER_MEAN_GAIN)} over 4 tests; "
        f"here {_percent(_nanmean([gain(f, baseline) for f in tests]))} over {len(tests)}",
        f"paired gain of the AnyScale tests (each against the baseline run just before it): "
        f"{_spread_cell(paired) if paired.count else 'no pair with both runs complete'}",
        f"best case (the network everywhere): paper {_percent(PAPER_BEST_CASE_GAIN)}; here "
        f"{_percent(gain(best, baseline)) if best else '-'}",
        f"share of the coverage bound's gain reached: here "
        f"{_percent(_nanmean([own_speed_share(f.bound) for f in tests]))} at each test's own "
        f"speeds; against the baselines "
        f"{_percent(_nanmean([bound_share(f, baseline) for f in tests]))}, against the paired "
        f"baselines {_percent(_nanmean([paired_bound_share(f, figures) for f in tests]))} (the "
        f"paper has no bound)",
        f"mean |w| against the baseline: paper about {_percent(PAPER_OMEGA_ABOVE_BASELINE)} "
        f"above; here {_percent(above)} {'above' if not above < 0 else 'below'}; turning per "
        f"metre driven {_percent(turning)} {'above' if not turning < 0 else 'below'} (the same "
        f"loop driven faster turns faster at the same corners)",
        f"highest mean |w|: limit of safe behaviour {SAFE_OMEGA_DEG_S:g} °/s; here "
        f"{_fixed(highest, ' °/s', 2)}"]


def shortfall_lines(figures: Sequence[RunFigures]) -> List[str]:
    """Per AnyScale test, and as a mean per allocator: the seconds it left of the coverage
    bound by cause, and what its moves out cost (evaluation_shortfall)."""
    def line(name: str, by_cause: Dict[str, float], moving: float) -> str:
        causes = ", ".join(f"{c} {by_cause[c]:.1f} s" for c in CAUSES)
        return (f"{name}: {sum(by_cause.values()):.1f} s ({causes}); moves out under way "
                f"{moving:.1f} s")
    lines = []
    for kind, runs in seeded_kinds(figures).items():
        judged = [f for f in runs if f.shortfall.by_cause]
        lines += [line(f.name, f.shortfall.by_cause, f.shortfall.moving_s) for f in judged]
        if len(judged) > 1:
            lines.append(line(f"mean {KIND_TITLES.get(kind, kind)}",
                              {c: _nanmean([f.shortfall.by_cause[c] for f in judged])
                               for c in CAUSES},
                              _nanmean([f.shortfall.moving_s for f in judged])))
    return lines


def violation_lines(figures: Sequence[RunFigures]) -> List[str]:
    return [f"{f.name}: {v.topic} silent {v.silence_s:.2f} s > Δ {v.tolerance_s:g} s from "
            f"t={v.start_t:.1f} s: {v.cause}" for f in figures for v in f.row.violations]


def format_table(figures: Sequence[RunFigures]) -> str:
    lines = table_lines(figures)
    widths = [max(len(line[i]) for line in lines) for i in range(len(lines[0]))]
    text = ["  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines]
    text += ["VIOLATION " + v for v in violation_lines(figures)]
    text += ["", "paper vs here:"] + ["  " + c for c in paper_comparison(figures)]
    text += ["", "left of the coverage bound, by cause:"] + \
        ["  " + c for c in shortfall_lines(figures)]
    return "\n".join(text)


def format_markdown(figures: Sequence[RunFigures], title: str) -> str:
    lines = table_lines(figures)
    md = [f"# {title}", "", "| " + " | ".join(lines[0]) + " |", "|" + "---|" * len(lines[0])]
    md += ["| " + " | ".join(c.replace("|", "/") for c in line) + " |" for line in lines[1:]]
    md += ["", "## The paper beside this test bed", ""]
    md += [f"- {c}" for c in paper_comparison(figures)]
    md += ["", "## What the tests left of the coverage bound, by cause", ""]
    md += [f"- {c}" for c in shortfall_lines(figures)] or ["no AnyScale test"]
    md += ["", "## Violations of a connection's tolerance", ""]
    md += [f"- {v}" for v in violation_lines(figures)] or ["none"]
    return "\n".join(md) + "\n"


def write_csv(path: str, figures: Sequence[RunFigures]):
    """One line per run, plain numbers (seconds, fractions 0..1, Hz, m/s, °/s, m); empty =
    unknown; premise_off 1 where AMCL ran off the premise at home."""
    topics = topics_of([f.row for f in figures])
    baseline = baseline_of(figures)
    with open(path, "w", newline="") as out:
        w = csv.writer(out)
        w.writerow(["run", "kind", "seed", "pair", "exit_code", "time_to_complete_s",
                    "gain_vs_baseline", "gain_vs_paired_baseline", "bound_time_s", "bound_gain",
                    "share_of_bound_gain", "bound_gain_vs_paired", "share_of_bound_gain_vs_paired",
                    "home_time_s", "share_of_bound_gain_own_speeds",
                    "driving_mps_amcl_home", "driving_mps_amcl_out",
                    "amcl_hz_every_node_home", "cruise_mps_every_node_home", "premise_off",
                    "mean_abs_omega_deg_s", "omega_ratio_to_baseline", "turning_deg_per_m",
                    "turning_ratio_to_baseline", "markers",
                    "amcl_rms_error_m"]
                   + [f"longest_silence_s {t}" for t in topics]
                   + [f"tolerance_s {t}" for t in topics]
                   + ["violations", "migrations"]
                   + [f"time_share {c}" for c in CONFIGURATIONS] + ["note"])
        for f in figures:
            paired = paired_baseline(f, figures)
            w.writerow([f.name, f.kind, f.seed, f.pair, f.row.exit_code,
                        _number(f.row.path_time_s), _number(gain(f, baseline)),
                        _number(gain(f, paired)), _number(f.bound.time_s),
                        _number(bound_gain(f, baseline)), _number(bound_share(f, baseline)),
                        _number(bound_gain(f, paired)), _number(bound_share(f, paired)),
                        _number(f.bound.home_time_s), _number(own_speed_share(f.bound)),
                        _number(f.bound.home_mps), _number(f.bound.out_mps),
                        _number(f.amcl_hz_home), _number(f.cruise_mps_home),
                        "" if not math.isfinite(f.amcl_hz_home) else
                        int(premise_is_off(f.amcl_hz_home)),
                        _number(f.mean_omega_deg_s),
                        _number(_ratio(f.mean_omega_deg_s,
                                       baseline.mean_omega_deg_s if baseline else None)),
                        _number(f.turning_deg_per_m),
                        _number(_ratio(f.turning_deg_per_m,
                                       baseline.turning_deg_per_m if baseline else None)),
                        f.markers, _number(f.rms_error_m)]
                       + [_number(f.row.longest_s.get(t, math.nan)) for t in topics]
                       + [_number(f.row.tolerances.get(t, math.nan)) for t in topics]
                       + [len(f.row.violations), f.row.migrations]
                       + [_number(f.shares.get(c, math.nan)) for c in CONFIGURATIONS]
                       + [note_cell(f)])


def _number(v: float) -> str:
    return "" if not math.isfinite(v) else f"{v:.4f}"
