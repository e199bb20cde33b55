"""The test bed's premise in figures (issue 13 item 0), from a run's record: per configuration
(where AMCL and AR ran), AMCL's rate and longest silence and the robot's speed. Pure (no ROS);
tests/bench/bench_premise.py runs the test bed and prints these; the evaluation
(evaluation_figures.py) checks each run's figures with every node home against the premise."""
import math
from typing import Dict, List, Optional

import numpy as np

from .testbed_record import TestbedRecord, mapping_at

SPEED_WINDOW_S = 5.0
# The robot also turns on the spot and waits at goals, where no rule limits its speed; the
# cruise speed is this percentile of the speed over SPEED_WINDOW_S windows.
CRUISE_PERCENTILE = 80
# The calibrated premise (anyscale_nav_demo/config/testbed_calibration.yaml,
# docs/measurements/premise.md): with every node on the robot AMCL sustains only its 2 Hz
# minimum. Runs at the calibrated quota varied by +-0.3 Hz; one further off than
# PREMISE_MARGIN_HZ did not run the premise (on a day this shared VM ran faster, AMCL ran at
# 2.9-3.1 Hz under that quota).
PREMISE_AMCL_HZ = 2.0
PREMISE_MARGIN_HZ = 0.5
# Start-up left out of a run's figures (bench_premise.py's --skip default).
START_UP_S = 30.0
COLUMNS = ["quota", "period_ms", "case", "configuration", "seconds", "amcl_hz",
           "amcl_longest_gap_s", "mean_speed", "cruise_speed", "joint_states_longest_gap_s"]


def configuration_name(mapping: Dict[str, str]) -> str:
    """The paper's configurations (Fig. 5's colours) by where AMCL and AR run."""
    return f"amcl@{mapping.get('amcl', '?')} ar@{mapping.get('ar_recognition', '?')}"


def path_length(truth: np.ndarray) -> float:
    """Metres driven along (t, x, y) rows."""
    return float(np.sum(np.hypot(np.diff(truth[:, 1]), np.diff(truth[:, 2])))) \
        if len(truth) >= 2 else 0.0


def speeds_over_windows(truth: np.ndarray, start: float, end: float) -> List[float]:
    """Speed (m/s) over each whole SPEED_WINDOW_S window of [start, end)."""
    out = []
    t = start
    while t + SPEED_WINDOW_S <= end:
        w = truth[(truth[:, 0] >= t) & (truth[:, 0] <= t + SPEED_WINDOW_S)]
        if len(w) >= 2 and w[-1, 0] > w[0, 0]:
            out.append(path_length(w) / (w[-1, 0] - w[0, 0]))
        t += SPEED_WINDOW_S
    return out


def configuration_spans(rec: TestbedRecord, start: float, end: float):
    """(configuration, t0, t1) spans of one mapping within [start, end)."""
    cuts = sorted({start, end} | {t for t, _, _, _ in rec.mappings if start < t < end})
    return [(configuration_name(mapping_at(rec, a)), a, b) for a, b in zip(cuts, cuts[1:])]


def longest_gap_after(receipts: List[float], skip_s: float) -> float:
    """The longest interval between receipts after skip_s (NaN with fewer than two)."""
    t = np.sort(np.asarray([x for x in receipts if x >= skip_s], dtype=float))
    return float(np.diff(t).max()) if len(t) >= 2 else float("nan")


def premise_figures(rec: TestbedRecord, skip_s: float) -> List[dict]:
    """Per configuration, after skip_s of start-up: seconds spent, AMCL's rate and longest
    interval between two of its poses within one span, mean and cruise speed. Spans shorter
    than two speed windows are left out (a move's own seconds say nothing of the
    configuration)."""
    end = rec.finished_t if rec.finished_t is not None else max(
        [t for t, _, _ in rec.truth] or [0.0])
    if end <= skip_s:
        return []
    truth = np.array(rec.truth, dtype=float).reshape(-1, 3)
    poses = np.array(rec.receipts.get("/amcl_pose", []), dtype=float)
    sums: Dict[str, dict] = {}
    for name, a, b in configuration_spans(rec, skip_s, end):
        if b - a < 2 * SPEED_WINDOW_S:
            continue
        s = sums.setdefault(name, {"seconds": 0.0, "poses": 0, "gap": 0.0, "dist": 0.0,
                                   "windows": []})
        inside = poses[(poses >= a) & (poses < b)]
        s["seconds"] += b - a
        s["poses"] += len(inside)
        if len(inside) >= 2:
            # Between poses only: a span's edges are the start-up cut, a move or the run's end,
            # and the silence up to one of those belongs to it, not to the configuration.
            s["gap"] = max(s["gap"], float(np.diff(inside).max()))
        s["dist"] += path_length(truth[(truth[:, 0] >= a) & (truth[:, 0] < b)])
        s["windows"] += speeds_over_windows(truth, a, b)
    return [{"configuration": name, "seconds": s["seconds"],
             "amcl_hz": s["poses"] / s["seconds"], "amcl_longest_gap_s": s["gap"],
             "mean_speed": s["dist"] / s["seconds"],
             "cruise_speed": (float(np.percentile(s["windows"], CRUISE_PERCENTILE))
                              if s["windows"] else math.nan)}
            for name, s in sorted(sums.items())]


EVERY_NODE_HOME = configuration_name({"amcl": "robot", "ar_recognition": "robot"})


def figures_with_every_node_home(rec: TestbedRecord,
                                 skip_s: float = START_UP_S) -> Optional[dict]:
    """premise_figures' row of the configuration with AMCL and AR on the robot; None where the
    run spent no span long enough there (the best case, a run without a mapping)."""
    return next((r for r in premise_figures(rec, skip_s)
                 if r["configuration"] == EVERY_NODE_HOME), None)


def premise_is_off(amcl_hz_home: float) -> bool:
    """AMCL's rate with every node home further than PREMISE_MARGIN_HZ from PREMISE_AMCL_HZ
    (False where unknown: NaN)."""
    return abs(amcl_hz_home - PREMISE_AMCL_HZ) > PREMISE_MARGIN_HZ


def premise_off_note(amcl_hz_home: float) -> str:
    """The table's flag of a run off the premise ("premise off: AMCL 3.0 Hz at home"), "" for
    one on it or unknown."""
    return f"premise off: AMCL {amcl_hz_home:.1f} Hz at home" \
        if premise_is_off(amcl_hz_home) else ""


def format_markdown(rows: List[dict]) -> str:
    lines = ["| robot quota | CFS period ms | run | configuration | s | AMCL Hz | "
             "AMCL longest gap s | mean m/s | cruise m/s | /joint_states longest gap s |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['quota']} | {r.get('period_ms', '100')} | {r['case']} | "
                     f"{r['configuration']} | {r['seconds']:.0f} | {r['amcl_hz']:.2f} | "
                     f"{r['amcl_longest_gap_s']:.2f} | {r['mean_speed']:.3f} | "
                     f"{r['cruise_speed']:.3f} | "
                     f"{r.get('joint_states_longest_gap_s', float('nan')):.3f} |")
    return "\n".join(lines) + "\n"
