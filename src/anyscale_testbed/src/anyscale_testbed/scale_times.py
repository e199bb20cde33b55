"""How long each node ran on each scale in a test-bed run, and the end table's lines of it
(testbed_figures.format_summary), from the record's mappings. Pure (no ROS).

The time is the decision node's: a node is on a scale from the mapping that places it there to
the next that does not. A move counts from its decision, so the seconds a new instance takes to
register (the event's duration, in the table of moves above it) count on the new scale, and a
move that failed counts on its target until a mapping places the node elsewhere.

The lines are shown on three scales or more (issue 39): on two, the configurations' lines of
premise_figures already say where AMCL and AR ran and for how long, and the two-scale table
stays as it was."""
from typing import Dict, List

from .testbed_record import TestbedRecord


def time_per_scale(rec: TestbedRecord, end: float) -> Dict[str, Dict[str, float]]:
    """node -> scale -> seconds the mappings placed it there, from the first mapping to `end`
    (a scale it never ran on is absent)."""
    out: Dict[str, Dict[str, float]] = {}
    starts = [t for t, _, _, _ in rec.mappings]
    for (t, mapping, _, _), until in zip(rec.mappings, starts[1:] + [end]):
        span = min(until, end) - t
        if span <= 0:
            continue            # replaced at once, or after the end
        for node, scale in mapping.items():
            per_scale = out.setdefault(node, {})
            per_scale[scale] = per_scale.get(scale, 0.0) + span
    return out


def scale_time_lines(rec: TestbedRecord, end: float) -> List[str]:
    """The end table's time per scale: a row for each node that may move (the record's outputs)
    or ran anywhere but the master, a column for each scale of the record (master first); none
    on fewer than three scales or without a mapping."""
    if len(rec.scales) < 3 or not rec.mappings:
        return []
    times = time_per_scale(rec, end)
    master = rec.scales[0]
    nodes = sorted(n for n, per_scale in times.items()
                   if n in rec.outputs or set(per_scale) - {master})
    if not nodes:
        return []
    columns = list(rec.scales) + sorted({s for n in nodes for s in times[n]} - set(rec.scales))
    first = rec.mappings[0][0]
    lines = [f"time per scale (the decision node's mapping, t={first:.1f} to {end:.1f} s):",
             f"  {'node':<16}" + "".join(f" {s:>9}" for s in columns)]
    for n in nodes:
        lines.append(f"  {n:<16}" + "".join(f" {seconds(times[n].get(s, 0.0)):>9}"
                                            for s in columns))
    return lines


def seconds(v: float) -> str:
    return f"{v:.0f} s" if v > 0 else "-"
