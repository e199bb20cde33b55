"""Output gaps per move over several test-bed runs, beside the node's own gaps when nothing
moves (pure, no ROS). A move's gap (testbed_figures.move_figures) is the longest silence of the
node's output in the move's window, and a node starved on the robot is silent now and then by
itself: the reference is the longest silence in windows of the same length, slid over the
stretches where the node ran at home and no node moved, restarted or lost its link nearby.
A move whose gaps look like that reference added no silence of its own. Where the record names
each message's sender, the silence right before the new instance's first message is the
handover's own (testbed_figures.handover_silence)."""
from dataclasses import dataclass
import math
from typing import List, Sequence, Tuple

import numpy as np

from .testbed_figures import gap_during, link_transitions, move_figures, move_window
from .testbed_record import TestbedRecord, mapping_at

# Kinds of move: a planned move out, a planned move back, a return forced by a link loss.
OUT, BACK, LINK_LOSS = "planned out", "planned back", "link-loss return"
# Stretches this close to a move, restart or link change are not "nothing moves".
QUIET_MARGIN_S = 3.0


def move_kind(kind: str, reason: str) -> str:
    if reason.startswith("link to"):
        return LINK_LOSS
    return OUT if kind == "migrate" else BACK


@dataclass(frozen=True)
class MoveGap:
    run: int
    node: str
    kind: str
    decided_t: float
    gap_s: float
    window_s: float
    handover_s: float = math.nan    # testbed_figures.handover_silence


def move_gaps(run: int, rec: TestbedRecord) -> List[MoveGap]:
    """Every move of a node with an output topic whose window ended within the record."""
    found = []
    for f in move_figures(rec, rec.outputs):
        if math.isfinite(f.output_gap_s):
            a, b = move_window(f.event)
            found.append(MoveGap(run, f.event.node, move_kind(f.event.kind, f.event.reason),
                                 f.event.decided_t, f.output_gap_s, b - a, f.handover_s))
    return found


def busy_spans(rec: TestbedRecord) -> List[Tuple[float, float]]:
    spans = [(e.decided_t - QUIET_MARGIN_S,
              move_window(e)[1] + QUIET_MARGIN_S if e.kind != "restart"
              else e.decided_t + 2 * QUIET_MARGIN_S)
             for e in rec.events if e.kind in ("migrate", "migrate_back", "restart", "start")]
    spans += [(t - QUIET_MARGIN_S, t + QUIET_MARGIN_S) for t, _ in link_transitions(rec.bandwidth)]
    return spans


def quiet_window_gaps(rec: TestbedRecord, node: str, window_s: float,
                      master: str = "robot") -> List[float]:
    """The longest silence of `node`'s output in each window of window_s (slid by half of it)
    within navigation's mission, with the node at home and nothing busy nearby."""
    times = sorted(rec.receipts.get(rec.outputs.get(node, ""), []))
    if len(times) < 2 or not rec.navigation_status or not window_s > 0:
        return []
    busy = busy_spans(rec)
    longest = []
    for start in np.arange(rec.navigation_status[0][0], times[-1] - window_s, window_s / 2):
        end = start + window_s
        if any(a <= end and start <= b for a, b in busy):
            continue
        if mapping_at(rec, start).get(node, master) != master:
            continue
        longest.append(gap_during(times, start, end))
    return longest


def _stats(values: Sequence[float]) -> str:
    v = np.asarray(values, dtype=float)
    return (f"median {np.median(v):.2f} s, p90 {np.percentile(v, 90):.2f} s, "
            f"worst {v.max():.2f} s")


def move_gap_lines(records: Sequence[Tuple[int, TestbedRecord]]) -> List[str]:
    """Per node and kind of move: how many, and their gaps; per node, its own reference."""
    gaps = [g for run, rec in records for g in move_gaps(run, rec)]
    lines = []
    for node in sorted({g.node for g in gaps}):
        mine = [g for g in gaps if g.node == node]
        for kind in (OUT, BACK, LINK_LOSS):
            these = [g for g in mine if g.kind == kind]
            if not these:
                continue
            worst = max(these, key=lambda g: g.gap_s)
            moves = f"{len(these)} move" + ("s" if len(these) != 1 else "")
            handovers = [g.handover_s for g in these if math.isfinite(g.handover_s)]
            handover = (f"; the silence before the new instance's first message: "
                        f"{_stats(handovers)}" if handovers else "")
            lines.append(f"{node} {kind}: {moves}, gap {_stats([g.gap_s for g in these])} "
                         f"(run {worst.run}, t={worst.decided_t:.1f} s){handover}")
        window = float(np.median([g.window_s for g in mine]))
        own = [x for _, rec in records for x in quiet_window_gaps(rec, node, window)]
        if own:
            lines.append(f"{node} at home, nothing moving: longest silence per {window:.1f} s "
                         f"window (a move's median window), {len(own)} windows: {_stats(own)}")
    return lines
