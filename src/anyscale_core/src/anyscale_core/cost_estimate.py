"""The live estimate of each node's CPU cost on each scale it may run on (no ROS): seeded from
the model's cpu_usage and learned from the agents' reports while the node runs there, so that
the allocators plan with what a node costs on a scale now rather than with a profile taken once.

A sample is the node's CPU in the model's unit (% of the scale's capacity: its quota, else its
cores). On a scale with room, or where the node meets its rates, that is what the node needs. On
a saturated scale where it falls short of them, it is the share the scheduler gave it, and the
node needs at least share x freq_opt / rate (a node's CPU grows with the messages it handles:
`anyscale profile` found the CPU per message the node's own cost, its CPU at a quota's limit not).
The master scale's figures are measured as they come: the model defines them as the node's CPU
at the rate the master sustains, and the master is exempt from the CPU limit.
"""
from collections import deque
from dataclasses import dataclass
import math
from statistics import median
from typing import Callable, Dict, List, Mapping, Tuple

import numpy as np

from .characterisation import Characterisation
from .constraints import SATURATED_PERCENT
from .decision_types import ScaleReport

# Samples whose median is learned from: a node's start (imports) or one sample taken across a
# stop is outvoted, a lasting change is not.
MEDIAN_OF = 5
# The least share of freq_opt a rate counts as in a saturated sample (a silent topic would
# make the need infinite; 20x the share is more than any scale has).
MIN_RATE_SHARE = 0.05
# A node at this share of its optimal rates or more got what it needs, saturated scale or not
# (`anyscale top` shows such a connection as ok): window rates jitter by a few per cent.
RATES_MET = 0.9
# Samples further apart than this belong to different stays of the node on the scale.
STAY_GAP_S = 5.0


class CostFilter:
    """One node's cost on one scale, % of the scale's capacity: the model's figure until the
    node runs there. The median of each stay's last MEDIAN_OF samples is learned from (once
    there are more than half of MEDIAN_OF, so that no single sample can be it);
    a median of direct samples by an exponential average over report time (time constant
    smoothing_s; 0: at once), which follows a lasting change within a few time constants
    whatever the report rate; a median of lower bounds (samples of a saturated scale) raises
    the estimate to itself at once and never lowers it. Not refreshed, the estimate relaxes
    toward the model's figure (time constant forget_s; 0: never): what a scale could give
    some minutes ago says less and less about what it can give now. A hold stops that until
    its end: a move sent back is retried when its back-off ends, and forgetting then runs
    from there, so that the wait grows with the back-off (held from the last sample, a lower
    bound relaxes back to a fit after the same time however often the move failed)."""

    def __init__(self, model_percent: float, smoothing_s: float, forget_s: float):
        self.model = model_percent
        self.smoothing_s = smoothing_s
        self.forget_s = forget_s
        self.measured = model_percent          # the estimate at the last sample
        self.last_t = -math.inf
        self.samples = 0
        self.lower_bound = False               # the latest median was of lower bounds
        self.window: deque = deque(maxlen=MEDIAN_OF)
        self.held = (math.inf, math.inf)      # [from, until): the estimate does not relax

    def value(self, t: float) -> float:
        """The estimate at time t."""
        if self.samples == 0 or self.forget_s <= 0 or t <= self.last_t:
            return self.measured
        start, end = self.held
        unheld = (t - self.last_t) - max(0.0, min(t, end) - max(self.last_t, start))
        return self.model + (self.measured - self.model) * math.exp(-unheld / self.forget_s)

    def hold(self, t: float, until: float):
        """From t, the estimate stays what it is at t until `until`, and relaxes from then."""
        if self.samples and until > t:
            self.measured, self.last_t = self.value(t), max(self.last_t, t)
            self.held = (self.last_t, until)

    def observe(self, t: float, percent: float, lower_bound: bool):
        """A sample at time t (a repeated or older one changes nothing)."""
        if not t > self.last_t or not math.isfinite(percent):
            return
        dt = t - self.last_t
        if dt > STAY_GAP_S:                    # a new stay: from what is believed now
            self.measured = self.value(t)
            self.window.clear()
            dt = 0.0
        self.held = (math.inf, math.inf)       # a sample there: the move is no longer held
        self.window.append((percent, lower_bound))
        self.last_t = t
        self.samples += 1
        if len(self.window) <= MEDIAN_OF // 2:
            return                             # one odd sample could still be the median
        level = median(p for p, _ in self.window)
        self.lower_bound = any(b for _, b in self.window)
        if self.lower_bound:
            self.measured = max(self.measured, level)
        elif self.smoothing_s <= 0:
            self.measured = level
        else:
            self.measured += (1.0 - math.exp(-dt / self.smoothing_s)) * (level - self.measured)


@dataclass(frozen=True)
class CostRow:
    """What is known of one node's cost on one scale at a moment (% of the scale's capacity)."""
    node: str
    scale: str
    model: float
    live: float            # what the allocators plan with
    measured: float        # when the node last ran there; NaN if never
    samples: int
    lower_bound: bool
    capacity_cores: float  # the scale's capacity when last learned there; NaN if never


class CostEstimates:
    """Every node's cost on every scale it may run on, learned from the agents' reports."""

    def __init__(self, ch: Characterisation, smoothing_s: float, forget_s: float):
        self.ch = ch
        self.filters: Dict[Tuple[int, int], CostFilter] = {
            (int(i), int(k)): CostFilter(float(ch.cpu[i, k]), smoothing_s, forget_s)
            for i, k in np.argwhere(ch.allowed)}
        self.outputs = [np.flatnonzero(ch.conn_pub == i) for i in range(ch.num_nodes)]
        self.inputs = [np.flatnonzero(ch.conn_sub == i) for i in range(ch.num_nodes)]
        self.capacity: Dict[str, float] = {}   # scale -> cores when a node was last learned
        self.learned = set()                   # (node, scale) observed at least once

    def observe(self, reports: Mapping[str, ScaleReport], assign: np.ndarray, now: float,
                fresh_s: float, settled: Callable[[int], bool]):
        """Learns from the latest report of each scale about every node mapped there that runs
        there and is `settled` (its start's CPU burst over: the decision engine's start-up
        grace); reports older than fresh_s say nothing."""
        for i, name in enumerate(self.ch.node_names):
            k = int(assign[i])
            report = reports.get(self.ch.scale_names[k])
            f = self.filters.get((i, k))
            if (f is None or report is None or name not in report.running
                    or now - report.received_at > fresh_s or not settled(i)):
                continue
            share = report.running[name] / max(report.capacity_cores, 1e-9)
            rates = self.rate_share(i, assign, reports) \
                if k != self.ch.master and report.cpu_percent >= SATURATED_PERCENT else 1.0
            bound = rates < RATES_MET
            f.observe(report.sample_time(), share / rates if bound else share, bound)
            self.capacity[report.scale] = report.capacity_cores
            self.learned.add((i, k))

    def rate_share(self, i: int, assign: np.ndarray, reports: Mapping[str, ScaleReport]) -> float:
        """How much of its optimal rates node i achieves: the best share of freq_opt among its
        outputs, each measured where its subscriber runs (its inputs for a node without a
        measured output; 1 if none is measured). Outputs: what a node publishes is the work it
        got done, where an input's rate says only that the agent there received it. The best,
        not the worst: an output can be slow for reasons of its own (its inputs, the link), and
        the need the best one implies is the least that is certain."""
        for connections in (self.outputs[i], self.inputs[i]):
            shares = []
            for c in connections:
                conn = self.ch.model.connections[c]
                report = reports.get(self.ch.scale_names[assign[self.ch.conn_sub[c]]])
                rate = report.topic_rates.get(conn.topic, math.nan) if report else math.nan
                if math.isfinite(rate):
                    shares.append(min(1.0, rate / conn.freq_opt))
            if shares:
                return max(max(shares), MIN_RATE_SHARE)
        return 1.0

    def hold(self, i: int, k: int, now: float, until: float):
        """Node i's estimate on scale k stays as it is now until `until` (CostFilter.hold)."""
        f = self.filters.get((i, k))
        if f is not None:
            f.hold(now, until)

    def live(self, i: int, k: int, now: float) -> float:
        f = self.filters.get((i, k))
        return f.value(now) if f is not None else float(self.ch.cpu[i, k])

    def matrix(self, now: float) -> np.ndarray:
        """(N, K) the live estimates on the remote scales, the model's figures on the master
        (exempt from the CPU limit, where the figure only orders the nodes), 0 where a node may
        not run."""
        cpu = self.ch.cpu.copy()
        for i, k in self.learned:
            if k != self.ch.master:
                cpu[i, k] = self.filters[i, k].value(now)
        return cpu

    def rows(self, now: float) -> List[CostRow]:
        out = []
        for (i, k), f in sorted(self.filters.items()):
            scale = self.ch.scale_names[k]
            out.append(CostRow(self.ch.node_names[i], scale, f.model, f.value(now),
                               f.measured if f.samples else math.nan, f.samples, f.lower_bound,
                               self.capacity.get(scale, math.nan) if f.samples else math.nan))
        return out
