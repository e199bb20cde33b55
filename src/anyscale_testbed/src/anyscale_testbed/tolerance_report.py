"""The tolerance bench's figures (tests/bench/bench_tolerances.py): one row per test-bed run,
read from its record.json (path time, migrations, restarts, the longest silence of each
connection's output against its tolerance, the violations the record kept), the table, the
total, and the CSV and Markdown copies. Pure (no ROS)."""
import bisect
import csv
from dataclasses import dataclass, field
import math
import statistics
from typing import Dict, List, Optional, Sequence

from .testbed_figures import judged_receipts, longest_gap
from .testbed_record import TestbedRecord, Violation


@dataclass
class RunRow:
    run: int                        # 1-based
    start_goal: int                 # the goal of the world's list the robot started at
    exit_code: int                  # run_testbed.py's
    seed: int = 0                   # the coverage's WiFi variation (0: the plain model)
    path_time_s: float = math.nan   # first navigation status -> "done"; NaN if not done
    migrations: int = 0             # moves out and back
    restarts: int = 0
    longest_s: Dict[str, float] = field(default_factory=dict)      # output topic -> silence
    tolerances: Dict[str, float] = field(default_factory=dict)     # output topic -> its Δ
    violations: List[Violation] = field(default_factory=list)
    # Each output's rate while every node ran on one scale (the robot: its drivers are pinned
    # there), the premise the run stood on; and the host's speed when the quotas followed it
    # (run_testbed.py --normalise-cpu: the median ms of its fixed workload; NaN otherwise).
    home_hz: Dict[str, float] = field(default_factory=dict)
    host_ms: float = math.nan
    note: str = ""                  # why a figure is missing, e.g. no record


def path_time(rec: TestbedRecord) -> float:
    """Seconds from navigation's first status to its first "done" (NaN if it never was)."""
    if not rec.navigation_status:
        return math.nan
    first = rec.navigation_status[0][0]
    done = [t for t, status in rec.navigation_status if status.startswith("done")]
    return done[0] - first if done else math.nan


def run_row(run: int, start_goal: int, exit_code: int,
            rec: Optional[TestbedRecord], seed: int = 0) -> RunRow:
    """The row of one run; without a record (the run failed early) only what is known."""
    row = RunRow(run, start_goal, exit_code, seed=seed)
    if rec is None:
        row.note = "no record"
        return row
    end = rec.finished_t if rec.finished_t is not None else max(
        [ts[-1] for ts in rec.receipts.values() if ts], default=0.0)
    row.path_time_s = path_time(rec)
    row.migrations = sum(e.kind in ("migrate", "migrate_back") for e in rec.events)
    row.restarts = sum(e.kind == "restart" for e in rec.events)
    row.tolerances = dict(rec.tolerances)
    for topic in rec.tolerances:
        times = judged_receipts(rec, topic)
        # Like the end table: from its connections' first message; one that never spoke has none.
        row.longest_s[topic] = longest_gap(times, times[0], end) if times else math.nan
    row.violations = list(rec.violations)
    row.home_hz = {t: rate_all_on_one_scale(rec, t, end) for t in rec.tolerances}
    if rec.cpu_normalisation:
        row.host_ms = statistics.median(ms for _, _, _, ms in rec.cpu_normalisation)
    if not rec.tolerances:
        row.note = "the record names no output tolerances (recorded before they were kept)"
    elif math.isnan(row.path_time_s):
        row.note = "the loop was not completed"
    return row


def rate_all_on_one_scale(rec: TestbedRecord, topic: str, end: float,
                          settle_s: float = 5.0, min_span_s: float = 10.0) -> float:
    """Messages per second on `topic` over the spans in which every node ran on one scale,
    each counted from `settle_s` after it began (a return's start-up is not the node's pace)
    and only if it lasted `min_span_s`; NaN if there was no such span."""
    times = sorted(rec.receipts.get(topic, []))
    marks = [m[0] for m in rec.mappings] + [end]
    count, span = 0, 0.0
    for (a, mapping, _, _), b in zip(rec.mappings, marks[1:]):
        if b - a < min_span_s or len(set(mapping.values())) != 1:
            continue
        a += settle_s
        count += bisect.bisect_left(times, b) - bisect.bisect_left(times, a)
        span += b - a
    return count / span if span > 0 else math.nan


def topics_of(rows: Sequence[RunRow]) -> List[str]:
    return sorted({t for r in rows for t in r.tolerances})


def silence_cell(row: RunRow, topic: str) -> str:
    """e.g. "1.21/2 s", "2.46/1 s !" (a silence above the tolerance), or "-"."""
    gap, tol = row.longest_s.get(topic, math.nan), row.tolerances.get(topic)
    if tol is None or math.isnan(gap):
        return "-"
    return f"{gap:.2f}/{tol:g} s" + (" !" if gap > tol else "")


def row_cells(row: RunRow, topics: Sequence[str]) -> List[str]:
    path = "-" if math.isnan(row.path_time_s) else f"{row.path_time_s:.0f} s"
    return ([str(row.run), str(row.start_goal), str(row.seed), str(row.exit_code), path,
             str(row.migrations),
             str(row.restarts)] + [silence_cell(row, t) for t in topics]
            + [_rate(row.home_hz.get(t, math.nan)) for t in topics]
            + ["-" if math.isnan(row.host_ms) else f"{row.host_ms:.1f}"]
            + [str(len(row.violations)), row.note])


def header(topics: Sequence[str]) -> List[str]:
    return (["run", "start goal", "seed", "exit", "path time", "migrations", "restarts"]
            + [f"{t} longest/tolerance" for t in topics]
            + [f"{t} Hz, all on one scale" for t in topics] + ["host ms", "violations", "note"])


def violation_line(row: RunRow, v: Violation) -> str:
    return (f"run {row.run}: {v.topic} silent {v.silence_s:.2f} s > tolerance "
            f"{v.tolerance_s:g} s from t={v.start_t:.1f} s: {v.cause}")


def total_line(rows: Sequence[RunRow]) -> str:
    violations = sum(len(r.violations) for r in rows)
    with_some = sum(bool(r.violations) for r in rows)
    times = [r.path_time_s for r in rows if not math.isnan(r.path_time_s)]
    path = f" (median path time {statistics.median(times):.0f} s)" if times else ""
    return (f"total: {len(rows)} runs, {violations} violations in {with_some} runs, "
            f"{len(times)} loops done{path}, {sum(r.migrations for r in rows)} migrations, "
            f"{sum(r.restarts for r in rows)} restarts")


def format_table(rows: Sequence[RunRow]) -> str:
    """The rows as aligned text, each run's violations under the table, and the total."""
    topics = topics_of(rows)
    table = [header(topics)] + [row_cells(r, topics) for r in rows]
    widths = [max(len(line[i]) for line in table) for i in range(len(table[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in table]
    lines += [f"VIOLATION {violation_line(r, v)}" for r in rows for v in r.violations]
    lines.append(total_line(rows))
    return "\n".join(lines)


def format_markdown(rows: Sequence[RunRow], title: str) -> str:
    topics = topics_of(rows)
    lines = [f"# {title}", "", "| " + " | ".join(header(topics)) + " |",
             "|" + "---|" * len(header(topics))]
    lines += ["| " + " | ".join(c.replace("|", "/") for c in row_cells(r, topics)) + " |"
              for r in rows]
    lines += ["", "## Violations", ""]
    lines += [f"- {violation_line(r, v)}" for r in rows for v in r.violations] or ["none"]
    lines += ["", total_line(rows), ""]
    return "\n".join(lines)


def write_csv(path: str, rows: Sequence[RunRow]):
    """One line per run; the violations of a run in one cell, separated by ' | '."""
    topics = topics_of(rows)
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["run", "start_goal", "seed", "exit_code", "path_time_s", "migrations",
                      "restarts"]
                     + [f"longest_silence_s {t}" for t in topics]
                     + [f"tolerance_s {t}" for t in topics]
                     + [f"hz_all_on_one_scale {t}" for t in topics] + ["host_ms"]
                     + ["violations", "violation_details", "note"])
        for r in rows:
            out.writerow([r.run, r.start_goal, r.seed, r.exit_code, _number(r.path_time_s),
                          r.migrations, r.restarts]
                         + [_number(r.longest_s.get(t, math.nan)) for t in topics]
                         + [_number(r.tolerances.get(t, math.nan)) for t in topics]
                         + [_number(r.home_hz.get(t, math.nan)) for t in topics]
                         + [_number(r.host_ms)]
                         + [len(r.violations),
                            " | ".join(violation_line(r, v) for v in r.violations), r.note])


def _rate(v: float) -> str:
    return "-" if math.isnan(v) else f"{v:.2f}"


def _number(v: float) -> str:
    return "" if math.isnan(v) else f"{v:.3f}"
