"""What a test-bed run recorded, and the figures drawn from it: gaps on output topics around
each migration, pose error against ground truth, how many live instances each migrated node
had while the link could carry their traffic. Pure (no ROS): the monitor node fills a
TestbedRecord, the system tests, the benchmarks and the end-of-run table read it."""
from dataclasses import asdict, dataclass, field
import bisect
import json
import math
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np


@dataclass
class EventRecord:
    t: float                # monitor clock (s since the run started) when it was received
    kind: str               # start, migrate, migrate_back, adopt, failed, restart
    node: str
    from_scale: str
    to_scale: str
    reason: str
    duration_s: float       # decision -> new instance registered; NaN if it was not
    success: bool
    decided_t: float        # when the decision was taken (the event's stamp), monitor clock


@dataclass
class ProcessSample:
    t: float
    link_up: bool                           # the modelled WiFi at that moment
    instances: Dict[str, List[str]]         # node -> network namespace of each live process


@dataclass
class TestbedRecord:
    __test__ = False        # not a pytest class
    started_wall: float = 0.0
    world: str = ""
    link: str = ""
    mappings: List[Tuple[float, Dict[str, str], float, float]] = field(default_factory=list)
    events: List[EventRecord] = field(default_factory=list)
    receipts: Dict[str, List[float]] = field(default_factory=dict)    # topic -> receive times
    truth: List[Tuple[float, float, float]] = field(default_factory=list)     # t, x, y
    estimate: List[Tuple[float, float, float]] = field(default_factory=list)  # AMCL's t, x, y
    bandwidth: List[Tuple[float, float]] = field(default_factory=list)  # t, modelled Mbit/s
    processes: List[ProcessSample] = field(default_factory=list)
    master_publishers: List[Tuple[float, Dict[str, List[str]]]] = field(default_factory=list)
    navigation_status: List[Tuple[float, str]] = field(default_factory=list)
    finished_t: Optional[float] = None

    def save(self, path: str):
        with open(path, "w") as f:
            json.dump(asdict(self), f, allow_nan=True)

    @staticmethod
    def load(path: str) -> "TestbedRecord":
        with open(path) as f:
            d = json.load(f)
        rec = TestbedRecord(**{k: v for k, v in d.items()
                               if k not in ("events", "processes")})
        rec.events = [EventRecord(**e) for e in d["events"]]
        rec.processes = [ProcessSample(**p) for p in d["processes"]]
        rec.mappings = [(t, m, p, o) for t, m, p, o in d["mappings"]]
        return rec


# --- figures ------------------------------------------------------------------------------------
def longest_gap(times: Sequence[float], start: float, end: float) -> float:
    """The longest silence within [start, end], counting the edges of the window."""
    inside = [t for t in times if start <= t <= end]
    points = [start] + inside + [end]
    return max(b - a for a, b in zip(points, points[1:])) if end > start else 0.0


def gap_during(times: Sequence[float], start: float, end: float) -> float:
    """The longest silence that overlaps [start, end] (a move's window), from the last message
    before it to the first after it (inf if the topic never spoke again)."""
    ordered = sorted(times)
    before = [t for t in ordered if t <= start][-1:] or [-math.inf]
    inside = [t for t in ordered if start < t <= end]
    after = [t for t in ordered if t > end][:1] or [math.inf]
    points = before + inside + after
    return max(b - a for a, b in zip(points, points[1:]))


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


def duplicate_instances(samples: Sequence[ProcessSample], nodes: Sequence[str]):
    """Samples where a node had more than one live process while the link was up, i.e. where
    two instances could both have been publishing: [(t, node, namespaces)]."""
    return [(s.t, n, s.instances.get(n, [])) for s in samples if s.link_up
            for n in nodes if len(s.instances.get(n, [])) > 1]


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


def mapping_at(rec: TestbedRecord, t: float) -> Dict[str, str]:
    current: Dict[str, str] = {}
    for when, mapping, _, _ in rec.mappings:
        if when > t:
            break
        current = mapping
    return current


# After the new instance registered, its first output may take this long (a filter's first
# update); the window of a move reaches this far past the registration.
MOVE_SETTLE_S = 3.0


@dataclass(frozen=True)
class MoveFigures:
    event: EventRecord
    output_gap_s: float        # the longest silence on the node's output topic during the move;
                               # NaN if the run ended before the move's window did
    first_output_s: float      # decision -> first message on the output topic afterwards


def move_figures(rec: TestbedRecord, outputs: Dict[str, str]) -> List[MoveFigures]:
    """For every migration of a node with a known output topic: the gap its subscriber saw."""
    out = []
    end = rec.finished_t if rec.finished_t is not None else _last_time(rec)
    for e in rec.events:
        topic = outputs.get(e.node)
        if e.kind not in ("migrate", "migrate_back") or topic is None:
            continue
        times = rec.receipts.get(topic, [])
        settled = e.decided_t + (e.duration_s if math.isfinite(e.duration_s) else 0.0)
        window_end = settled + MOVE_SETTLE_S
        gap = gap_during(times, e.decided_t, window_end) if window_end <= end else math.nan
        out.append(MoveFigures(e, gap, first_after(times, e.decided_t)))
    return out


def format_summary(rec: TestbedRecord, outputs: Dict[str, str],
                   tolerances: Dict[str, float]) -> str:
    """The end-of-run table: moves, gaps, localisation, link."""
    lines = [f"=== AnyScale test-bed run: world {rec.world}, link {rec.link}, "
             f"{(rec.finished_t or _last_time(rec)):.0f} s"]
    moves = [e for e in rec.events if e.kind in ("migrate", "migrate_back")]
    failed = [e for e in rec.events if e.kind == "failed"]
    lines.append(f"migrations: {sum(e.kind == 'migrate' for e in moves)} out, "
                 f"{sum(e.kind == 'migrate_back' for e in moves)} back, {len(failed)} failed")
    for e in rec.events:
        if e.kind == "restart":
            lines.append(f"  restarted {e.node} at t={e.decided_t:.1f} s: {e.reason}")
    figures = move_figures(rec, outputs)
    if figures:
        lines.append(f"  {'t [s]':>7}  {'node':<16} {'move':<20} {'registered':>10} "
                     f"{'output gap':>10}  reason")
        for f in figures:
            e = f.event
            lines.append(f"  {e.decided_t:7.1f}  {e.node:<16} "
                         f"{e.from_scale + ' -> ' + e.to_scale:<20} "
                         f"{_seconds(e.duration_s):>10} {_seconds(f.output_gap_s):>10}  "
                         f"{e.reason}")
    end = rec.finished_t or _last_time(rec)
    for topic, tol in sorted(tolerances.items()):
        times = rec.receipts.get(topic, [])
        if times:
            gap = longest_gap(times, times[0], end)
            lines.append(f"{topic}: longest silence {gap:.2f} s (tolerance {tol:g} s) "
                         f"after its first message")
    errors = pose_errors(rec.truth, rec.estimate)
    if errors.size:
        lines.append(f"AMCL position error vs ground truth: RMS {np.sqrt(np.mean(errors**2)):.3f}"
                     f" m, max {errors.max():.3f} m over {errors.size} poses")
    if rec.bandwidth:
        up = np.array([b > 0 for _, b in rec.bandwidth])
        lines.append(f"link: up {100 * up.mean():.0f} % of the samples, "
                     f"{len(link_transitions(rec.bandwidth))} up/down changes")
    if rec.mappings:
        _, _, perf, objective = rec.mappings[-1]
        lines.append(f"Perf of the last mapping (Eq. 1): {perf:.1f}; objective so far "
                     f"(Eq. 2): {objective:.0f}")
    return "\n".join(lines)


def _seconds(v: float) -> str:
    return f"{v:.2f} s" if math.isfinite(v) else "-"


def _last_time(rec: TestbedRecord) -> float:
    candidates = [rec.truth[-1][0]] if rec.truth else []
    candidates += [ts[-1] for ts in rec.receipts.values() if ts]
    return max(candidates, default=0.0)
