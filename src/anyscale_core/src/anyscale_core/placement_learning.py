"""What the decision engine learns from its placements (no ROS), in the engine's terms (agent
reports, mappings, moves): the live cost estimates the allocators plan with (cost_estimate.py)
and the back-off of moves sent back for rate or CPU (placement_backoff.py).

A return counts as a failed placement when the scale could not give the node what it needs:
the node's estimate no longer fits the scale's load (CPU), or a connection of the node spent its
tolerance while the scale was saturated, or ran slow (still delivering, below freq_min) while
the link carried the streams with margin: the scale's doing, not the link's. A return for the
link (down, bandwidth, a weak link) is none, nor is a rate on a scale with room over a link
that may not carry it (the link's own rules handle that), nor a silence on a scale with room
(an instance that died with its agent, or a stalled link, says nothing of the scale's room).
"""
from dataclasses import dataclass, replace
import math
from typing import AbstractSet, Callable, Dict, FrozenSet, List, Mapping, Optional, Tuple

import numpy as np

from .characterisation import Characterisation
from .constraints import (CPU_CAPACITY_PERCENT, SATURATED_PERCENT, DynamicState,
                          required_bandwidth)
from .cost_estimate import CostEstimates, CostRow
from .decision_types import DecisionParams, ScaleReport
from .placement_backoff import Backoff, PlacementBackoff, PlacementBackoffParams, describe


# A link with this many times the bandwidth of the streams that cross it, and this share of
# its technology's nominal bandwidth (13.5 of 802.11g's 54 Mbit/s; the office floor's coverage
# gives 27 where it is good, 3-8 at its edges, where loss and retries stall streams whatever
# their size), does not make them slow: a rate short on the scale they reach is the scale's.
LINK_MARGIN = 2.0
LINK_NOMINAL_SHARE = 0.25


@dataclass(frozen=True)
class PlacementRow:
    """One node's cost on one scale, and the back-off of its move there."""
    cost: CostRow
    retry_in_s: float            # 0: not backed off
    failures: int                # returns for rate or CPU in a row since the last success
    reason: str                  # the latest such return's


class PlacementLearning:
    """The engine calls observe() each tick, plans with planning() and blocked(), tells
    left() of each move away from a remote scale and settle() of the mapping after the tick."""

    def __init__(self, ch: Characterisation, params: DecisionParams):
        self.ch = ch
        self.params = params
        self.learning = params.learning
        self.costs = CostEstimates(ch, self.learning.cost_smoothing_s,
                                   self.learning.cost_forget_s)
        self.backoff = PlacementBackoff(PlacementBackoffParams(
            params.hysteresis_s, self.learning.backoff_max_s, self.learning.success_s,
            self.learning.retry_room))
        self.busy: Dict[str, Tuple[float, float]] = {}   # scale -> (report time, smoothed CPU)

    def observe(self, reports: Mapping[str, ScaleReport], assign: np.ndarray, now: float,
                settled: Callable[[int], bool]):
        """Learns from the latest reports (a report seen before teaches nothing new)."""
        self.costs.observe(reports, assign, now, self.params.status_timeout_s, settled)
        for scale, r in reports.items():
            last = self.busy.get(scale)
            if last is not None and r.received_at <= last[0]:
                continue
            # The scale's whole CPU, averaged as its background load is (cpu_smoothing_s).
            tau = self.params.cpu_smoothing_s
            weight = 1.0 if last is None or tau <= 0 else \
                1.0 - math.exp(-(r.received_at - last[0]) / tau)
            value = r.cpu_percent if last is None else last[1] + weight * (r.cpu_percent - last[1])
            self.busy[scale] = (r.received_at, value)

    def cost(self, i: int, k: int, now: float) -> float:
        """Node i's cost on scale k as the allocators see it."""
        return self.costs.live(i, k, now) if self.learning.plan_with_estimates \
            else float(self.ch.cpu[i, k])

    def planning(self, now: float) -> Characterisation:
        """The characterisation the allocators plan with: the live estimates as CPU costs.
        Eq. 1's values stay the model's: they state what a placement is worth to the user."""
        if not self.learning.plan_with_estimates:
            return self.ch
        return replace(self.ch, cpu=self.costs.matrix(now))

    def load(self, i: int, k: int, assign: np.ndarray, state: DynamicState, now: float) -> float:
        """Scale k's load without node i (% of its capacity): its background load and the
        costs of the other nodes mapped there."""
        others = [j for j in np.flatnonzero(assign == k) if j != i]
        return state.scale_load.get(self.ch.scale_names[k], 0.0) + \
            sum(self.cost(int(j), k, now) for j in others)

    def blocked(self, assign: np.ndarray, state: DynamicState,
                now: float) -> FrozenSet[Tuple[int, int]]:
        """(node, scale) moves the back-off holds back now. Only a report of the scale received
        after the failure can show that its load dropped: one sent before a refusal may show
        the room another robot took since."""
        out = set()
        for i, k in list(self.backoff.backoffs):
            if assign[i] == k:
                continue
            load = self.load(i, k, assign, state, now)
            fits = load + self.cost(i, k, now) <= SATURATED_PERCENT + 1e-9
            seen = self.busy.get(self.ch.scale_names[k], (-math.inf, 0.0))[0]
            if seen <= self.backoff.backoffs[i, k].at:
                load = math.inf
            if self.backoff.blocked((i, k), now, load, fits):
                out.add((i, k))
        return frozenset(out)

    def left(self, i: int, k: int, now: float, assign: np.ndarray, state: DynamicState,
             violating: Mapping[int, str],
             slow_rate: AbstractSet[int] = frozenset()) -> Optional[Tuple[str, str]]:
        """Node i was moved away from remote scale k (`assign`: the mapping it left;
        `violating`: the nodes whose connections spent their tolerance, and why; `slow_rate`:
        those of them still delivering, below freq_min). For a failed placement: a few words
        for the move's reason and the back-off's log line."""
        key = (i, k)
        scale = self.ch.scale_names[k]
        load = self.load(i, k, assign, state, now)
        cost = self.cost(i, k, now)
        busy = self.busy.get(scale, (0.0, 0.0))[1]
        if not state.up_vector(self.ch)[k]:
            reason = ""
        elif load + cost > CPU_CAPACITY_PERCENT + 1e-9:
            reason = f"{scale} CPU {load:.0f} % + {cost:.0f} % estimated for it"
        elif i in violating and busy >= SATURATED_PERCENT:
            reason = f"{violating[i]}, {scale} {busy:.0f} % busy"
        elif i in slow_rate and self.link_carries(assign, state):
            reason = f"{violating[i]}, the link at {state.bandwidth_mbps:.0f} Mbit/s"
        else:
            reason = ""
        if not reason:
            self.backoff.left(key)
            return None
        b = self.failed(key, now, load, load + cost <= CPU_CAPACITY_PERCENT, reason)
        if b is None:
            return None
        return (f"backed off {b.delay_s:g} s",
                describe(self.ch.node_names[i], scale, b, self.learning.retry_room))

    def failed(self, key: Tuple[int, int], now: float, load: float, fitted: bool,
               reason: str) -> Optional[Backoff]:
        """Backs the move off; its cost estimate is held as learned until the back-off ends,
        so that forgetting does not bring the move back before it (CostFilter.hold)."""
        b = self.backoff.failed(key, now, load, fitted, reason)
        if b is not None:
            self.costs.hold(*key, now, b.until)
        return b

    def link_carries(self, assign: np.ndarray, state: DynamicState) -> bool:
        """The link is not a slow rate's cause: its bandwidth is LINK_MARGIN x what crosses it
        in `assign` or more, LINK_NOMINAL_SHARE of the model's nominal or more, and not below
        weak_link_mbps."""
        need = required_bandwidth(self.ch, assign)
        nominal = self.ch.model.network.max_bandwidth_mbps
        return state.bandwidth_mbps >= max(self.params.weak_link_mbps, LINK_MARGIN * need,
                                           LINK_NOMINAL_SHARE * nominal)

    def refused(self, i: int, k: int, now: float, assign: np.ndarray, state: DynamicState,
                cpu_free: float, memory_free: float) -> List[str]:
        """Scale k's ledger refused node i, having room for cpu_free % and memory_free MB
        (`assign`: the mapping with node i not there). A refusal is a CPU failure: node i, and
        every other node that does not fit that room either, is backed off there, its load the
        more of the scale's load without it and what the ledger holds, so that the back-off
        ends early once the scale's reports show room (other robots' nodes gone). The back-offs'
        log lines."""
        scale = self.ch.scale_names[k]
        lines = []
        for j in np.flatnonzero(self.ch.allowed[:, k]):
            j = int(j)
            cost, memory = self.cost(j, k, now), float(self.ch.memory[j])
            if assign[j] == k or (j != i and cost <= cpu_free + 1e-9
                                  and memory <= memory_free + 1e-9):
                continue
            load = max(self.load(j, k, assign, state, now), CPU_CAPACITY_PERCENT - cpu_free)
            short = f"{cost:.0f} % > {cpu_free:.0f} % free" if cost > cpu_free + 1e-9 else \
                f"{memory:.0f} MB > {memory_free:.0f} MB free"
            b = self.failed((j, k), now, load, True, f"{scale} full: {short}")
            if b is not None:
                lines.append(describe(self.ch.node_names[j], scale, b, self.learning.retry_room,
                                      refused=j == i))
        return lines

    def settle(self, assign: np.ndarray, now: float) -> List[str]:
        """Follows where the nodes are after a tick; the lines of back-offs reset by a stay."""
        for i, k in enumerate(assign):
            if k != self.ch.master and (i, int(k)) not in self.backoff.stays:
                self.backoff.moved((i, int(k)), now)
        for i, k in list(self.backoff.stays):
            if assign[i] != k:
                self.backoff.left((i, k))
        return [f"{self.ch.node_names[i]} ran on {self.ch.scale_names[k]} for "
                f"{self.learning.success_s:g} s without a return for rate or CPU: its back-off "
                f"there is reset" for i, k in self.backoff.settle(now)]

    def rows(self, now: float) -> List[PlacementRow]:
        out = []
        for row in self.costs.rows(now):
            key = (self.ch.node_index(row.node), self.ch.scale_index(row.scale))
            b = self.backoff.get(key)
            out.append(PlacementRow(row, self.backoff.retry_in(key, now),
                                    b.failures if b else 0, b.reason if b else ""))
        return out
