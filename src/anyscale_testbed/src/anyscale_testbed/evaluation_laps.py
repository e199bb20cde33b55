"""Lap by lap, the evaluation's figures of a run that drove its loop more than once
(run_evaluation.py --laps N): the decision node's link map learns on lap 1 what lap 2 can use.
Per lap: the time, the coverage bound over the lap (evaluation_figures.coverage_bound) and the
share of its gain reached, at the lap's own speeds and against the baseline's same lap, the
returns by kind (after a link loss, planned before a hole, other), the worst output gap per
kind of move, and the silences longer than Δ. Pure (no ROS)."""
import csv
from dataclasses import dataclass, field
import math
import os
import re
from typing import Dict, List, Optional, Sequence, Tuple

from .evaluation_figures import NO_BOUND, CoverageBound, coverage_bound, own_speed_share
from .testbed_figures import move_figures
from .testbed_record import (LINK_AHEAD_RETURN, LINK_LOSS_RETURN, MOVE_KINDS, OTHER_RETURN,
                             TestbedRecord, kind_of_move)

_STATUS = re.compile(r"\S+ (\d+)/(\d+)$")


def lap_windows(rec: TestbedRecord, laps: int) -> List[Tuple[float, float]]:
    """(start, end) of each lap on the record's clock: navigation's goals are the loop's goals
    repeated `laps` times, and lap L ends at the first status with L x (goals per lap) done;
    end NaN for a lap not completed (and for every lap when the goals do not divide)."""
    parsed = [(t, int(m.group(1)), int(m.group(2))) for t, s in rec.navigation_status
              for m in [_STATUS.match(s)] if m]
    if not parsed or laps < 1:
        return []
    total = parsed[0][2]
    per_lap = total // laps if total % laps == 0 else 0
    windows, start = [], parsed[0][0]
    for lap in range(1, laps + 1):
        ends = [t for t, done, _ in parsed if per_lap and done >= lap * per_lap]
        end = ends[0] if ends else math.nan
        windows.append((start, end))
        start = end
    return windows


@dataclass
class LapFigures:
    lap: int
    time_s: float                   # NaN: not completed
    bound_time_s: float             # the coverage bound over the lap
    bound: CoverageBound = NO_BOUND
    returns: Dict[str, int] = field(default_factory=dict)        # kind -> count, every node
    amcl_returns: Dict[str, int] = field(default_factory=dict)   # kind -> count, AMCL's
    worst_gap_s: Dict[str, float] = field(default_factory=dict)  # move kind -> longest gap
    violations: int = 0


RETURN_KINDS = (LINK_LOSS_RETURN, LINK_AHEAD_RETURN, OTHER_RETURN)


def lap_figures(rec: TestbedRecord, laps: int, amcl_mbps: float,
                master: str = "robot") -> List[LapFigures]:
    """One LapFigures per lap (a lap not completed has NaN times and counts up to the run's
    end)."""
    moves = move_figures(rec, rec.outputs)
    out = []
    for lap, (start, end) in enumerate(lap_windows(rec, laps), 1):
        done = math.isfinite(end)
        stop = end if done else math.inf
        inside = [e for e in rec.events if start <= e.decided_t < stop]
        bound = coverage_bound(rec, amcl_mbps, master, (start, end)) if done else NO_BOUND
        f = LapFigures(lap, end - start if done else math.nan, bound.time_s, bound)
        for kind in RETURN_KINDS:
            f.returns[kind] = sum(kind_of_move(e) == kind for e in inside)
            f.amcl_returns[kind] = sum(kind_of_move(e) == kind and e.node == "amcl"
                                       for e in inside)
        for kind in MOVE_KINDS:
            gaps = [m.output_gap_s for m in moves if kind_of_move(m.event) == kind
                    and start <= m.event.decided_t < stop and math.isfinite(m.output_gap_s)]
            f.worst_gap_s[kind] = max(gaps, default=math.nan)
        f.violations = sum(start <= v.start_t < stop for v in rec.violations)
        out.append(f)
    return out


def lap_share(test: LapFigures, baseline_time_s: float) -> float:
    """The share of the coverage bound's gain the lap reached against the baseline's same lap:
    (baseline - test) / (baseline - bound); NaN where there is no gain to reach."""
    reachable = baseline_time_s - test.bound_time_s
    if not (math.isfinite(reachable) and reachable > 0 and math.isfinite(test.time_s)):
        return math.nan
    return (baseline_time_s - test.time_s) / reachable


@dataclass(frozen=True)
class LapRow:
    """One lap of one run, beside its baseline (the paired one, else the baselines' mean)."""
    run: str
    figures: LapFigures
    baseline_s: float


def lap_rows(runs: Sequence[Tuple[str, str, int, List[LapFigures]]]) -> List[LapRow]:
    """runs: (name, kind, pair, laps) per run. The baselines give each lap's reference: the
    same pair's baseline, else the mean of every baseline's same lap."""
    baselines = [(pair, laps) for _, kind, pair, laps in runs if kind == "baseline"]
    rows = []
    for name, kind, pair, laps in runs:
        if kind in ("baseline", "best_case"):
            continue
        for f in laps:
            rows.append(LapRow(name, f, _baseline_lap(baselines, pair, f.lap)))
    return rows


def _baseline_lap(baselines, pair: int, lap: int) -> float:
    def time_of(laps):
        return next((f.time_s for f in laps if f.lap == lap), math.nan)
    own = [time_of(laps) for p, laps in baselines if pair and p == pair]
    if own and math.isfinite(own[0]):
        return own[0]
    times = [t for t in (time_of(laps) for _, laps in baselines) if math.isfinite(t)]
    return sum(times) / len(times) if times else math.nan


HEADER = ["run", "lap", "time", "baseline lap", "bound", "share of bound's gain at own speeds",
          "share of bound's gain",
          "link-loss returns (AMCL)", "planned returns before a hole (AMCL)",
          "other returns (AMCL)"] + [f"worst gap: {k}" for k in MOVE_KINDS] + ["violations"]


def _cells(row: LapRow) -> List[str]:
    f = row.figures

    def s(v, digits=0):
        return f"{v:.{digits}f} s" if math.isfinite(v) else "-"

    def percent(v):
        return f"{100 * v:.0f} %" if math.isfinite(v) else "-"
    return ([row.run, str(f.lap), s(f.time_s), s(row.baseline_s), s(f.bound_time_s),
             percent(own_speed_share(f.bound)), percent(lap_share(f, row.baseline_s))]
            + [f"{f.returns[k]} ({f.amcl_returns[k]})" for k in RETURN_KINDS]
            + [s(f.worst_gap_s[k], 2) for k in MOVE_KINDS] + [str(f.violations)])


def format_laps(rows: Sequence[LapRow]) -> List[str]:
    """Aligned text lines, a header and a line per lap."""
    lines = [HEADER] + [_cells(r) for r in rows]
    widths = [max(len(line[i]) for line in lines) for i in range(len(HEADER))]
    return ["  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines]


def markdown_laps(rows: Sequence[LapRow]) -> List[str]:
    return (["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
            + ["| " + " | ".join(_cells(r)) + " |" for r in rows])


def write_laps_csv(path: str, rows: Sequence[LapRow]):
    """One line per lap; seconds, shares 0..1; empty = unknown."""
    def n(v):
        return "" if v is None or not math.isfinite(v) else f"{v:.4f}"
    with open(path, "w", newline="") as out:
        w = csv.writer(out)
        w.writerow(["run", "lap", "time_s", "baseline_lap_s", "bound_time_s",
                    "share_of_bound_gain", "share_of_bound_gain_own_speeds"]
                   + [f"returns {k}" for k in RETURN_KINDS]
                   + [f"amcl_returns {k}" for k in RETURN_KINDS]
                   + [f"worst_gap_s {k}" for k in MOVE_KINDS] + ["violations"])
        for r in rows:
            f = r.figures
            w.writerow([r.run, f.lap, n(f.time_s), n(r.baseline_s), n(f.bound_time_s),
                        n(lap_share(f, r.baseline_s)), n(own_speed_share(f.bound))]
                       + [f.returns[k] for k in RETURN_KINDS]
                       + [f.amcl_returns[k] for k in RETURN_KINDS]
                       + [n(f.worst_gap_s[k]) for k in MOVE_KINDS] + [f.violations])


def laps_of(figures) -> Optional[List[Tuple[str, str, int, List[LapFigures]]]]:
    """(name, kind, pair, laps) of every run with lap figures (RunFigures.laps); None if none
    has them (a one-lap evaluation)."""
    runs = [(f.name, f.kind, f.pair, f.laps) for f in figures if f.laps]
    return runs or None


def write_lap_report(out: str, figures) -> List[str]:
    """The lap table's lines (also appended to evaluation.txt and .md, and as
    evaluation_laps.csv in `out`); [] for a one-lap evaluation."""
    runs = laps_of(figures)
    if runs is None:
        return []
    rows = lap_rows(runs)
    lines = ["", "lap by lap (link-loss / planned returns: every node's, AMCL's in brackets):"]
    lines += ["  " + line for line in format_laps(rows)]
    with open(os.path.join(out, "evaluation.txt"), "a") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(out, "evaluation.md"), "a") as f:
        f.write("\n## Lap by lap\n\nReturns: every node's, AMCL's in brackets.\n\n"
                + "\n".join(markdown_laps(rows)) + "\n")
    write_laps_csv(os.path.join(out, "evaluation_laps.csv"), rows)
    return lines
