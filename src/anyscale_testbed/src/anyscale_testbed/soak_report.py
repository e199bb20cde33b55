"""The fault soak's table, pure (no ROS): from the verdicts of soak_invariants.py, a row per
fault kind (count, recovered, worst and median recovery, worst output silence against its Δ,
violations), the findings below it, the verdict, and CSV and Markdown copies."""
from dataclasses import dataclass
import csv
import math
import statistics
from typing import List, Sequence, Tuple

from .fault_schedule import KINDS
from .soak_growth import Growth
from .soak_invariants import FaultOutcome


@dataclass
class KindRow:
    kind: str
    faults: int
    not_injected: int
    recovered: int
    worst_recovery_s: float
    median_recovery_s: float
    worst_silence: Tuple[str, float, float]
    violations: int


def kind_rows(outcomes: Sequence[FaultOutcome]) -> List[KindRow]:
    rows = []
    for kind in KINDS:
        mine = [o for o in outcomes if o.kind == kind]
        judged = [o for o in mine if not o.injected.error]
        times = [o.recovery_s for o in judged]
        finite = [t for t in times if math.isfinite(t)]
        silences = [o.worst_silence for o in judged if o.worst_silence[0]]
        rows.append(KindRow(
            kind, len(mine), len(mine) - len(judged), len(finite),
            max(times) if times else math.nan,
            statistics.median(finite) if finite else math.nan,
            max(silences, key=lambda w: w[1] / w[2], default=("", 0.0, 0.0)),
            sum(len(o.violations) for o in judged)))
    return rows


HEADER = ["fault kind", "count", "recovered", "worst recovery", "median recovery",
          "worst output silence / Δ", "violations"]


def _cells(r: KindRow) -> List[str]:
    injected = r.faults - r.not_injected
    count = f"{r.faults}" + (f" ({r.not_injected} not injected)" if r.not_injected else "")
    return [r.kind, count, f"{r.recovered}/{injected}", _seconds(r.worst_recovery_s),
            _seconds(r.median_recovery_s),
            f"{r.worst_silence[1]:.2f}/{r.worst_silence[2]:g} s {r.worst_silence[0]}"
            if r.worst_silence[0] else "-", str(r.violations)]


def _seconds(v: float) -> str:
    if math.isnan(v):
        return "-"
    return "never" if math.isinf(v) else f"{v:.2f} s"


def total_line(outcomes: Sequence[FaultOutcome], leaks: Sequence[str],
               growths: Sequence[Growth], unchecked: Sequence[str] = ()) -> str:
    violations = sum(len(o.violations) for o in outcomes)
    grew = [g for g in growths if g.grew]
    return (f"total: {len(outcomes)} faults, {violations} violations, {len(leaks)} leaks, "
            f"{len(grew)} processes grew" + (f", {len(unchecked)} NOT CHECKED" if unchecked
                                             else ""))


def verdict_ok(outcomes: Sequence[FaultOutcome], leaks: Sequence[str],
               growths: Sequence[Growth]) -> bool:
    return (not any(o.violations for o in outcomes) and not leaks
            and not any(g.grew for g in growths)
            and not any(o.injected.error for o in outcomes))


def detail_lines(outcomes: Sequence[FaultOutcome], leaks: Sequence[str],
                 growths: Sequence[Growth], unchecked: Sequence[str] = (),
                 notes: Sequence[str] = ()) -> List[str]:
    """Below the table: faults not injected, each violation with its fault, `notes` on them
    (e.g. who had the CPU), the leaks, the growth of each process judged, and what could not be
    checked (named, so that a soak never passes an invariant by without saying so)."""
    lines = [f"NOT INJECTED fault {o.index} {o.kind} at t={o.injected.t:.1f} s: "
             f"{o.injected.error}" for o in outcomes if o.injected.error]
    for o in outcomes:
        for v in o.violations:
            lines.append(f"VIOLATION fault {o.index} {o.kind} at t={o.injected.t:.1f} s "
                         f"({o.injected.fault.describe()}): {v}")
    lines += list(notes)
    lines += [f"LEAK {x}" for x in leaks]
    for g in growths:
        state = "GREW " + "; ".join(g.grew) if g.grew else "steady"
        lines.append(f"{g.role} pid {g.pid} over {g.span_s:.0f} s: memory {g.rss_first_mb:.1f}"
                     f" -> {g.rss_last_mb:.1f} MB, fds besides connections {g.fds_first:g}"
                     f" -> {g.fds_last:g}: {state}")
    return lines + [f"NOT CHECKED {x}" for x in unchecked]


def format_table(outcomes: Sequence[FaultOutcome], leaks: Sequence[str],
                 growths: Sequence[Growth], unchecked: Sequence[str] = (),
                 notes: Sequence[str] = ()) -> str:
    table = [HEADER] + [_cells(r) for r in kind_rows(outcomes)]
    widths = [max(len(line[i]) for line in table) for i in range(len(HEADER))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in table]
    return "\n".join(lines + detail_lines(outcomes, leaks, growths, unchecked, notes)
                     + [total_line(outcomes, leaks, growths, unchecked)])


def format_markdown(outcomes: Sequence[FaultOutcome], leaks: Sequence[str],
                    growths: Sequence[Growth], title: str, unchecked: Sequence[str] = (),
                    notes: Sequence[str] = ()) -> str:
    lines = [f"# {title}", "", "| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(_cells(r)) + " |" for r in kind_rows(outcomes)]
    lines += ["", "## Faults", "", "| # | t [s] | kind | what | recovery | violations |",
              "|---|---|---|---|---|---|"]
    for o in outcomes:
        what = o.injected.fault.describe() + (f" ({o.injected.detail})" if o.injected.detail
                                              else "")
        recovery = ("not injected: " + o.injected.error if o.injected.error
                    else _seconds(o.recovery_s))
        lines.append(f"| {o.index} | {o.injected.t:.1f} | {o.kind} | {what} | {recovery}"
                     f" | {len(o.violations)} |")
    lines += ["", "## Findings", ""]
    lines += [f"- {x}" for x in detail_lines(outcomes, leaks, growths, unchecked, notes)] or \
        ["none"]
    lines += ["", total_line(outcomes, leaks, growths, unchecked), ""]
    return "\n".join(lines)


def write_csv(path: str, outcomes: Sequence[FaultOutcome]):
    """One line per fault kind, then one per fault (its violations in one cell)."""
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["row", "kind", "faults", "recovered", "worst_recovery_s",
                      "median_recovery_s", "worst_silence_topic", "worst_silence_s",
                      "tolerance_s", "violations"])
        for r in kind_rows(outcomes):
            out.writerow(["kind", r.kind, r.faults - r.not_injected, r.recovered,
                          _number(r.worst_recovery_s), _number(r.median_recovery_s),
                          r.worst_silence[0], _number(r.worst_silence[1]) if r.worst_silence[0]
                          else "", _number(r.worst_silence[2]) if r.worst_silence[0] else "",
                          r.violations])
        out.writerow([])
        out.writerow(["row", "index", "kind", "t_s", "what", "detail", "error", "recovery_s",
                      "worst_silence_topic", "worst_silence_s", "violations",
                      "violation_details"])
        for o in outcomes:
            out.writerow(["fault", o.index, o.kind, f"{o.injected.t:.2f}",
                          o.injected.fault.describe(), o.injected.detail, o.injected.error,
                          _number(o.recovery_s), o.worst_silence[0],
                          _number(o.worst_silence[1]) if o.worst_silence[0] else "",
                          len(o.violations), " | ".join(o.violations)])


def _number(v: float) -> str:
    if math.isnan(v):
        return ""
    return "inf" if math.isinf(v) else f"{v:.3f}"
