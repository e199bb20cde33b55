"""The end table's CPU costs: per node and scale, the model's figure beside the live estimate
the decision node planned with at the end and what it learned there (pure, from the record)."""
import math
from typing import List

from .testbed_record import TestbedRecord


def cost_lines(rec: TestbedRecord) -> List[str]:
    """Lines for the end table; none for a record without estimates (an older one, or a run
    without a decision node)."""
    if not rec.cost_estimates:
        return []
    lines = ["CPU cost per node and scale (% of the scale's capacity): the model's figure, the "
             "live estimate at the end, as last learned there (≥: a lower bound, learned on a "
             "saturated scale):"]
    for c in rec.cost_estimates:
        measured = c.get("measured_percent")
        learned = "not learned" if not c.get("samples") or measured is None \
            or not math.isfinite(measured) else \
            (f"learned {'≥' if c.get('lower_bound') else ''}{measured:.0f} from "
             f"{c['samples']} reports")
        failures = c.get("failures") or 0
        lines.append(f"  {c['node']:<16} {c['scale']:<8} model {c['model_percent']:>5.0f}  "
                     f"live {c['live_percent']:>5.0f}  {learned}"
                     + (f"; {failures} return(s) for rate or CPU in a row" if failures else ""))
    return lines
