"""The figures of one test-bed run, drawn from its record (testbed_record.py): gaps on output
topics around each migration, silences longer than a connection's tolerance (violations), pose
error against ground truth, how many live instances each migrated node had while the link could
carry their traffic, and the end-of-run table. Pure (no ROS)."""
from dataclasses import dataclass
import bisect
import math
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from anyscale_core.constraints import SATURATED_PERCENT

from .cost_figures import cost_lines
from .premise_figures import (EVERY_NODE_HOME, PREMISE_AMCL_HZ, START_UP_S, premise_figures,
                              premise_off_note)
from .scale_times import scale_time_lines
from .testbed_record import (LINK_AHEAD_RETURN, LINK_LOSS_RETURN, OTHER_RETURN, EventRecord,
                             ProcessSample, TestbedRecord, Violation, kind_of_move, mapping_at)


def longest_gap(times: Sequence[float], start: float, end: float) -> float:
    """The longest silence within [start, end], counting the edges of the window."""
    inside = [t for t in times if start <= t <= end]
    points = [start] + inside + [end]
    return max(b - a for a, b in zip(points, points[1:])) if end > start else 0.0


def gap_during(times: Sequence[float], start: float, end: float) -> float:
    """The longest silence that overlaps [start, end] (a move's window), from the last message
    before it to the first after it (inf if the topic never spoke again)."""
    return max(b - a for a, b in silences_overlapping(times, start, end))


def silences_overlapping(times: Sequence[float], start: float,
                         end: float) -> List[Tuple[float, float]]:
    """The silences (last message, next message) that overlap [start, end], in time order;
    -inf / inf where the topic had not spoken before or never spoke again."""
    ordered = sorted(times)
    before = [t for t in ordered if t <= start][-1:] or [-math.inf]
    inside = [t for t in ordered if start < t <= end]
    after = [t for t in ordered if t > end][:1] or [math.inf]
    points = before + inside + after
    return list(zip(points, points[1:]))


def silences_longer_than(times: Sequence[float], limit: float,
                         end: float) -> List[Tuple[float, float]]:
    """The silences longer than `limit` from the first message to `end`: (last message before,
    first message after, or `end` if none came). Before its first message a topic is starting,
    not silent."""
    ordered = sorted(t for t in times if t <= end)
    points = ordered + [end] if ordered else []
    return [(a, b) for a, b in zip(points, points[1:]) if b - a > limit]


def first_after(times: Sequence[float], moment: float) -> float:
    """Seconds from `moment` to the first message after it (inf if none)."""
    ordered = sorted(times)
    i = bisect.bisect_right(ordered, moment)
    return ordered[i] - moment if i < len(ordered) else math.inf


def reaction_s(times: Sequence[float], down: float, decided: float) -> float:
    """Link down -> the first message on the node's output after the move back was decided
    (inf if none). Messages before the decision are the remote instance's: in flight when the
    link went, or sent in the few ms between the shaper's record of the change and the link
    going down."""
    return max(decided, down) - down + first_after(times, max(decided, down))


def pose_errors(truth: Sequence[Tuple[float, float, float]],
                estimate: Sequence[Tuple[float, float, float]]) -> np.ndarray:
    """Position error of each estimate against the ground truth interpolated at its time."""
    if len(truth) < 2 or not estimate:
        return np.zeros(0)
    tt, tx, ty = (np.asarray(c, dtype=float) for c in zip(*truth))
    et, ex, ey = (np.asarray(c, dtype=float) for c in zip(*estimate))
    inside = (et >= tt[0]) & (et <= tt[-1])
    gx = np.interp(et[inside], tt, tx)
    gy = np.interp(et[inside], tt, ty)
    return np.hypot(ex[inside] - gx, ey[inside] - gy)


# A planned move runs the old and the new instance side by side until the new one has
# published (make before break): from its decision to at most this long after the new
# instance registered.
HANDOVER_S = 5.0


def handover_windows(events: Sequence[EventRecord], overlap_s: float = HANDOVER_S
                     ) -> Dict[str, List[Tuple[float, float]]]:
    """node -> (start, end) of each planned move's overlap, up to overlap_s past the new
    instance's registration (a slower host takes longer to its first outputs). A return forced
    by a link loss has none: its old instance could not be reached, and its lease ends it."""
    out: Dict[str, List[Tuple[float, float]]] = {}
    for e in events:
        if e.kind in ("migrate", "migrate_back") and not e.reason.startswith("link to"):
            registered = e.duration_s if math.isfinite(e.duration_s) else 0.0
            out.setdefault(e.node, []).append(
                (e.decided_t, e.decided_t + registered + overlap_s))
    return out


def duplicate_instances(samples: Sequence[ProcessSample], nodes: Sequence[str],
                        events: Sequence[EventRecord] = (), overlap_s: float = HANDOVER_S):
    """Samples where a node had more than one live process while the link was up, i.e. where
    two instances could both have been publishing, outside the overlap of a planned move
    among `events`: [(t, node, namespaces)]."""
    windows = handover_windows(events, overlap_s)
    return [(s.t, n, s.instances.get(n, [])) for s in samples if s.link_up
            for n in nodes if len(s.instances.get(n, [])) > 1
            and not any(a <= s.t <= b for a, b in windows.get(n, []))]


def link_transitions(bandwidth: Sequence[Tuple[float, float]]) -> List[Tuple[float, bool]]:
    """(t, up) each time the modelled link went down (0 Mbit/s) or came back."""
    out, up = [], None
    for t, mbps in bandwidth:
        now_up = mbps > 0
        if now_up != up:
            if up is not None:
                out.append((t, now_up))
            up = now_up
    return out


# After the new instance registered, its first output may take this long (a filter's first
# update); the window of a move reaches this far past the registration.
MOVE_SETTLE_S = 3.0
# A silence may begin this long before the decision of the move it belongs to: a move back
# forced by a link loss is decided after the link went, and the last message the link
# carried came up to one period of the output at its freq_min before that (1 s for AR's
# 1 Hz, 0.5 s for AMCL's 2 Hz).
MOVE_LEAD_S = 1.0


@dataclass(frozen=True)
class MoveFigures:
    event: EventRecord
    # The longest silence on the node's output topic that this move owns (see move_figures);
    # NaN if the run ended before the move's window did, or if it was decided in a silence it
    # does not own.
    output_gap_s: float
    first_output_s: float      # decision -> first message on the output topic afterwards
    # The output was already silent when the move was decided, since then (a silence this move
    # does not own).
    silent_since_t: float = math.nan
    # The silence before the first message of another sender in the move's window
    # (handover_silence).
    handover_s: float = math.nan


def handover_silence(rec: TestbedRecord, topic: str, start: float, end: float) -> float:
    """The silence that ended with the first message from a new sender within [start, end]:
    from the last message before it (of any sender) to it. 0-ish when the old instance still
    published as the new one began (make before break). NaN if the record names no senders
    (recorded before they were kept) or no new sender spoke in the window."""
    changes = [t for t, _ in rec.senders.get(topic, []) if start <= t <= end]
    if not changes:
        return math.nan
    before = [t for t in rec.receipts.get(topic, []) if t < changes[0]]
    return changes[0] - before[-1] if before else math.nan


def move_window(e: EventRecord) -> Tuple[float, float]:
    """From the decision to MOVE_SETTLE_S after the new instance registered."""
    settled = e.decided_t + (e.duration_s if math.isfinite(e.duration_s) else 0.0)
    return e.decided_t, settled + MOVE_SETTLE_S


def move_figures(rec: TestbedRecord, outputs: Dict[str, str]) -> List[MoveFigures]:
    """For every migration of a node with a known output topic: the gap its subscriber saw.
    A silence belongs to one move at most: the first one whose window it overlaps and that was
    decided no more than MOVE_LEAD_S after it began. A later move in the same silence reports
    since when the output was silent instead of counting the silence a second time."""
    end = record_end(rec)
    owned: Dict[str, set] = {}          # topic -> starts of the silences a move owns
    figures = {}
    moves = [e for e in rec.events if e.kind in ("migrate", "migrate_back") and e.node in outputs]
    for e in sorted(moves, key=lambda e: e.decided_t):
        topic = outputs[e.node]
        times = rec.receipts.get(topic, [])
        start, window_end = move_window(e)
        first = first_after(times, e.decided_t)
        if window_end > end:
            figures[id(e)] = MoveFigures(e, math.nan, first)
            continue
        handover = handover_silence(rec, topic, start, window_end)
        overlapping = silences_overlapping(times, start, window_end)
        taken = owned.setdefault(topic, set())
        mine = [(a, b) for a, b in overlapping if a >= start - MOVE_LEAD_S and a not in taken]
        taken.update(a for a, _ in mine)
        if overlapping[0] in mine:
            gap = max(b - a for a, b in mine)
            figures[id(e)] = MoveFigures(e, gap, first, handover_s=handover)
        else:   # what follows in its window is the output coming back, not this move's gap
            figures[id(e)] = MoveFigures(e, math.nan, first, overlapping[0][0], handover)
    return [figures[id(e)] for e in moves]


def judged_from(rec: TestbedRecord, topic: str) -> float:
    """When the connections on `topic` exist: the latest of its subscribers' first starts
    (-inf where the record names no subscribers, or one of them was not started by AnyScale,
    as a static node is not: its connection exists from the start). Before it
    the output reaches nobody: during the initial configuration on a 0.25-core robot, AR
    recognition publishes from about t=16 s and navigation, its subscriber, runs from about
    t=26 s, and the nodes starting in between held /ar_markers back 1.1 s once (tolerance
    bench); that is the node set coming up, with the robot standing, not a connection's
    silence."""
    started = {}
    for e in rec.events:
        if e.kind == "start" and e.success and e.node not in started:
            started[e.node] = e.t
    subs = rec.subscribers.get(topic, [])
    if not subs or any(n not in started for n in subs):
        return -math.inf
    return max(started[n] for n in subs)


def judged_receipts(rec: TestbedRecord, topic: str) -> List[float]:
    """The topic's receive times from when its connections exist (judged_from). An output
    already publishing then starts with `since` itself: a silence under way when its
    connections came up counts from that moment."""
    since = judged_from(rec, topic)
    receipts = rec.receipts.get(topic, [])
    after = [t for t in receipts if t >= since]
    if len(after) < len(receipts) and math.isfinite(since):
        return [since] + after
    return after


def tolerance_violations(rec: TestbedRecord, outputs: Optional[Dict[str, str]] = None,
                         tolerances: Optional[Dict[str, float]] = None,
                         end: Optional[float] = None) -> List[Violation]:
    """Every silence of an output topic longer than its connection's tolerance Δ (the
    record's own outputs and tolerances unless given), with what happened around it, up to
    `end` (the record's end unless given)."""
    outputs = rec.outputs if outputs is None else outputs
    tolerances = rec.tolerances if tolerances is None else tolerances
    end = record_end(rec) if end is None else end
    found = []
    for topic, tol in sorted(tolerances.items()):
        if tol <= 0:
            continue            # a critical connection: pinned, never moved, no Δ to keep
        nodes = {n for n, t in outputs.items() if t == topic}
        for a, b in silences_longer_than(judged_receipts(rec, topic), tol, end):
            found.append(Violation(topic, a, b, b - a, tol,
                                   silence_cause(rec, nodes, a, b, ran_to_end=b >= end,
                                                 topic=topic)))
    return sorted(found, key=lambda v: v.start_t)


def silence_cause(rec: TestbedRecord, nodes, start: float, end: float,
                  ran_to_end: bool = False, topic: str = "") -> str:
    """What happened to the topic's publishers and the link from shortly before a silence
    began to its end, in time order, in words."""
    near = [(t, f"link {'back' if up else 'down'} at t={t:.1f} s")
            for t, up in link_transitions(rec.bandwidth) if start - MOVE_LEAD_S <= t <= end]
    node = min(nodes) if nodes else ""
    scale = mapping_at(rec, start).get(node, "")
    others = []         # other nodes starting on the silent node's scale: their start loads it
    for e in rec.events:
        first, last = move_window(e)
        if first > end or last < start - MOVE_LEAD_S:
            continue
        move = f" {e.from_scale} -> {e.to_scale}" if e.from_scale else f" on {e.to_scale}"
        if e.node in nodes:
            near.append((e.decided_t, f"{e.kind} {e.node}{move} at t={e.decided_t:.1f} s "
                                      f"({e.reason})"))
        elif scale and e.to_scale == scale:
            others.append((e.decided_t, f"{e.kind} {e.node}{move} at t={e.decided_t:.1f} s, "
                                        f"starting on the {scale} as {node} fell silent"))
    words = [w for _, w in sorted(near)] or ["no move, restart or link change of "
                                             f"{', '.join(sorted(nodes)) or 'its publisher'}"]
    words += [w for _, w in sorted(others)]
    if ran_to_end:
        words.append("silent until the run ended")
    load = scale_load(rec, scale, start, end)
    inputs = input_gaps(rec, start, end)
    return "; ".join(words + [w for w in (rate_before(rec, topic, node, start), load, inputs)
                              if w])


# How far back rate_before looks: a few of a starved AMCL's updates.
RATE_BEFORE_S = 10.0


def rate_before(rec: TestbedRecord, topic: str, node: str, start: float) -> str:
    """The topic's rate over RATE_BEFORE_S before a silence, in words, where one scale ran its
    publisher `node` all that time: a node that was already below its minimum rate there is
    told from one that stopped at once. "" otherwise."""
    scale = mapping_at(rec, start).get(node, "")
    if not topic or not scale or start < RATE_BEFORE_S or any(
            m.get(node) != scale for t, m, _, _ in rec.mappings
            if start - RATE_BEFORE_S < t < start):
        return ""
    n = sum(1 for t in rec.receipts.get(topic, []) if start - RATE_BEFORE_S <= t < start)
    return f"{topic} at {n / RATE_BEFORE_S:.1f} Hz on the {scale} in the {RATE_BEFORE_S:g} s before"


def scale_load(rec: TestbedRecord, scale: str, start: float, end: float) -> str:
    """How busy the scale that ran the silent node was from `start` to `end`, from its agent's
    reports, in words: whether the node was starved of CPU. "" where none was recorded."""
    busy = [pct for t, pct in rec.scale_cpu.get(scale, []) if start <= t <= end]
    if not busy:
        return ""
    mean = sum(busy) / len(busy)
    return (f"{scale} CPU {mean:.0f} % busy over the silence"
            + (" (at its limit)" if mean >= SATURATED_PERCENT else ""))


def input_gaps(rec: TestbedRecord, start: float, end: float) -> str:
    """The longest gap of each recorded input (rec.inputs) from `start` to `end`, in words:
    whether a silent node was starved of its inputs or slow on them. "" if none is recorded."""
    parts = []
    for topic in rec.inputs:
        times = sorted(t for t in rec.receipts.get(topic, []) if start <= t <= end)
        points = [start] + times + [end]
        gap, at = max((b - a, a) for a, b in zip(points, points[1:]))
        parts.append(f"{topic} {gap:.2f} s" + (f" from t={at:.1f} s" if gap > 0.5 else ""))
    return ("longest input gaps at the monitor: " + ", ".join(parts)) if parts else ""


# The word that marks a violation in the end table: plain in a log file, and red where the
# table is printed to a terminal (colour_violations).
VIOLATION = "VIOLATION"


def colour_violations(line: str, terminal: bool) -> str:
    """The line in red if it reports a violation and goes to a terminal, else as it is."""
    return f"\033[31m{line}\033[0m" if terminal and VIOLATION in line else line


def format_summary(rec: TestbedRecord, outputs: Dict[str, str],
                   tolerances: Dict[str, float]) -> str:
    """The end-of-run table: moves, gaps, localisation, link. A move's output gap is the longest
    silence of the node's output in its window; its handover, the silence right before the new
    instance's first message (handover_silence)."""
    lines = [f"=== AnyScale test-bed run: world {rec.world}, link {rec.link}, "
             f"{(rec.finished_t or _last_time(rec)):.0f} s"]
    moves = [e for e in rec.events if e.kind in ("migrate", "migrate_back")]
    failed = [e for e in rec.events if e.kind == "failed"]
    lines.append(f"migrations: {sum(e.kind == 'migrate' for e in moves)} out, "
                 f"{sum(e.kind == 'migrate_back' for e in moves)} back, {len(failed)} failed")
    kinds = [kind_of_move(e) for e in moves]
    lines.append(f"  returns: {kinds.count(LINK_LOSS_RETURN)} after a link loss, "
                 f"{kinds.count(LINK_AHEAD_RETURN)} planned before a hole (link ahead), "
                 f"{kinds.count(OTHER_RETURN)} other planned")
    for e in rec.events:
        if e.kind == "restart":
            lines.append(f"  restarted {e.node} at t={e.decided_t:.1f} s: {e.reason}")
    figures = move_figures(rec, outputs)
    if figures:
        lines.append(f"  {'t [s]':>7}  {'node':<16} {'move':<20} {'registered':>10} "
                     f"{'output gap':>10} {'handover':>9}  reason")
        for f in figures:
            e = f.event
            since = (f"; output silent since t={f.silent_since_t:.1f} s, before this move"
                     if math.isfinite(f.silent_since_t) else "")
            lines.append(f"  {e.decided_t:7.1f}  {e.node:<16} "
                         f"{e.from_scale + ' -> ' + e.to_scale:<20} "
                         f"{_seconds(e.duration_s):>10} {_seconds(f.output_gap_s):>10} "
                         f"{_seconds(f.handover_s):>9}  {e.reason}{since}")
    end = rec.finished_t or _last_time(rec)
    for topic, tol in sorted(tolerances.items()):
        times = judged_receipts(rec, topic)
        if times:
            gap = longest_gap(times, times[0], end)
            since = ("once its subscribers ran" if math.isfinite(judged_from(rec, topic))
                     else "after its first message")
            lines.append(f"{topic}: longest silence {gap:.2f} s (tolerance {tol:g} s) {since}")
    violations = tolerance_violations(rec, outputs, tolerances)
    lines.append(f"silences longer than their tolerance: {len(violations) or 'none'}")
    for v in violations:
        lines.append(f"  {VIOLATION} {v.topic}: silent {v.silence_s:.2f} s > tolerance "
                     f"{v.tolerance_s:g} s from t={v.start_t:.1f} to {v.end_t:.1f} s: {v.cause}")
    errors = pose_errors(rec.truth, rec.estimate)
    if errors.size:
        lines.append(f"AMCL position error vs ground truth: RMS {np.sqrt(np.mean(errors**2)):.3f}"
                     f" m, max {errors.max():.3f} m over {errors.size} poses")
    lines += premise_lines(rec)
    lines += scale_time_lines(rec, end)
    lines += cost_lines(rec)
    if rec.bandwidth:
        up = np.array([b > 0 for _, b in rec.bandwidth])
        lines.append(f"link: up {100 * up.mean():.0f} % of the samples, "
                     f"{len(link_transitions(rec.bandwidth))} up/down changes")
    if rec.mappings:
        _, _, perf, objective = rec.mappings[-1]
        lines.append(f"Perf of the last mapping (Eq. 1): {perf:.1f}; objective so far "
                     f"(Eq. 2): {objective:.0f}")
    return "\n".join(lines)


def premise_lines(rec: TestbedRecord) -> List[str]:
    """Where AMCL and AR ran, and what AMCL's rate and the robot's speed were there: the test
    bed's premise is AMCL at its 2 Hz minimum (0.2 m/s) with every node on the robot, and the
    robot at 0.4 m/s with AMCL on the laptop."""
    rows = premise_figures(rec, START_UP_S) if rec.mappings else []
    if not rows:
        return []
    lines = [f"per configuration, after {START_UP_S:g} s of start-up (premise: AMCL "
             f"{PREMISE_AMCL_HZ:g} Hz with every node on the robot):"]
    for r in rows:
        off = premise_off_note(r["amcl_hz"]) if r["configuration"] == EVERY_NODE_HOME else ""
        lines.append(f"  {r['configuration']:<26} {r['seconds']:5.0f} s  AMCL "
                     f"{r['amcl_hz']:.2f} Hz (longest gap {r['amcl_longest_gap_s']:.2f} s)  "
                     f"cruise {r['cruise_speed']:.2f} m/s" + (f"  {off}" if off else ""))
    return lines


def _seconds(v: float) -> str:
    return f"{v:.2f} s" if math.isfinite(v) else "-"


def record_end(rec: TestbedRecord) -> float:
    """When the run ended: the monitor's finish, else its last sample (a killed run)."""
    return rec.finished_t if rec.finished_t is not None else _last_time(rec)


def _last_time(rec: TestbedRecord) -> float:
    candidates = [rec.truth[-1][0]] if rec.truth else []
    candidates += [ts[-1] for ts in rec.receipts.values() if ts]
    return max(candidates, default=0.0)
