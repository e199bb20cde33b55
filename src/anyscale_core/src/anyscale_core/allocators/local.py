"""`paper_local`: the paper's heuristic (Algorithm 1 to its fixpoint), then improved by local search
that keeps every constraint: moves of one node or one chain of connected nodes, pairs of such
moves (swaps included), and a move made room for by sending a few remote nodes back.

Algorithm 1 places nodes greedily by CPU usage; when bandwidth or a scale's CPU binds, the greedy
order can leave much of Eq. 1 unused (bench_allocator_quality.py). A pair move lets one node make
room for another (out of a scale or off the network), which single moves cannot; moving a chain
of connected nodes together keeps the traffic between them off the network.

The search is anytime: each round moves to a better feasible mapping, and when the time budget
runs out the decision is the mapping reached so far (never below the paper's decision).
"""
import time
from typing import Callable, Optional

import numpy as np

from ..characterisation import Characterisation
from ..constraints import CPU_CAPACITY_PERCENT, DynamicState, admission_state, is_feasible
from .base import (DEFAULT_TIME_BUDGET_S, AllocationContext, Decision, Deadline,
                   candidate_scales, moves_between)
from .move_delta import EPS, UnitDeltas, excess, over, totals_of
from .paper import PaperAllocator

# Improvements smaller than this are rounding, not worth a migration.
_MIN_GAIN = 1e-6


class PaperLocalAllocator:
    name = "paper_local"

    def __init__(self, max_pair_moves: int = 120, max_rounds: int = 200,
                 max_ejection_tries: int = 20, max_ejections: int = 10,
                 time_budget_s: Optional[float] = DEFAULT_TIME_BUDGET_S,
                 clock: Callable[[], float] = time.monotonic):
        self.max_pair_moves = max_pair_moves   # single moves combined into pairs, at most
        self.max_rounds = max_rounds
        self.max_ejection_tries = max_ejection_tries   # best moves tried with ejections
        self.max_ejections = max_ejections             # nodes sent back to make room, at most
        self.time_budget_s = time_budget_s     # s per decision; None: search to the end
        self.clock = clock

    def decide(self, ch: Characterisation, assign: np.ndarray, state: DynamicState,
               ctx: AllocationContext) -> Decision:
        out_of_time = Deadline(self.time_budget_s, self.clock)
        current = PaperAllocator().decide(ch, assign, state, ctx).assign
        state = admission_state(ch, assign, state)
        if is_feasible(ch, current, state):
            search = _Search(ch, state, candidate_scales(ch, state, ctx), self)
            for _ in range(self.max_rounds):
                moves = search.unit_moves(current)
                better = None
                for phase in (search.best_single, search.best_pair, search.best_ejection):
                    if out_of_time():
                        break
                    better = phase(current, moves, out_of_time)
                    if better is not None:
                        break
                if better is None:
                    break
                current = better
        return Decision(current, moves_between(ch, assign, current, "higher Perf (local search)",
                                               "constraints (paper, then local search)"))

    # One decision period: the search converges (or runs out of its budget) within the period.
    step = decide


class _UnitMoves:
    """Every move of a unit to a scale all its nodes may use now, as parallel arrays in the
    order units, then scales: unit, scale, Eq. 1 gain; with the table and the mapping's totals."""

    def __init__(self, unit, scale, table, totals):
        self.unit, self.scale, self.table, self.totals = unit, scale, table, totals
        self.gain = table.gain[unit, scale]


class _Search:
    """The moves of the local search from one feasible mapping (each returns a better feasible
    mapping, or None)."""

    def __init__(self, ch: Characterisation, state: DynamicState, mask: np.ndarray, limits):
        self.ch, self.limits = ch, limits
        self.load, self.limit = state.load_vector(ch), state.bandwidth_mbps
        units = movable_units(ch)
        members = np.zeros((len(units), ch.num_nodes), dtype=bool)
        for u, nodes in enumerate(units):
            members[u, nodes] = True
        self.units = UnitDeltas(ch, members)
        self.nodes = UnitDeltas(ch)
        # (U, K): every node of the unit may run on k now
        self.unit_allowed = (members.astype(float) @ ~mask) == 0

    def unit_moves(self, current) -> _UnitMoves:
        table = self.units.table(current)
        unit, scale = np.nonzero(self.unit_allowed & (table.count > 0))
        return _UnitMoves(unit, scale, table, totals_of(self.ch, current, self.load))

    def _apply(self, current, unit, scale):
        new = current.copy()
        new[self.units.members[unit]] = scale
        return new

    def best_single(self, current, moves: _UnitMoves, out_of_time):
        """The best unit move that keeps every constraint: as the mapping keeps them, only the
        move's target scale needs checking."""
        ch, t, tot, u, k = self.ch, moves.table, moves.totals, moves.unit, moves.scale
        ok = (moves.gain > _MIN_GAIN) \
            & ((k == ch.master) | (tot.cpu[k] + t.cpu[u, k] <= CPU_CAPACITY_PERCENT + EPS)) \
            & (tot.memory[k] + t.memory[u, k] <= ch.scale_memory[k] + EPS) \
            & (tot.bandwidth + t.bandwidth[u, k] <= self.limit + EPS)
        if not ok.any():
            return None
        j = int(np.argmax(np.where(ok, moves.gain, -np.inf)))
        return self._apply(current, u[j], k[j])

    def best_pair(self, current, moves: _UnitMoves, out_of_time):
        ch, tot, gain = self.ch, moves.totals, moves.gain
        if len(gain) < 2:
            return None
        chosen = np.arange(len(gain))
        if len(gain) > self.limits.max_pair_moves:
            # Half the most promising moves, half the cheapest ways to free room (moves back).
            half = self.limits.max_pair_moves // 2
            order = np.argsort(-gain, kind="stable")
            back = order[moves.scale[order] == ch.master][:half]
            ahead = order[~np.isin(order, back)][:self.limits.max_pair_moves - len(back)]
            chosen = np.concatenate([ahead, back])
        unit, scale, gain = moves.unit[chosen], moves.scale[chosen], gain[chosen]
        a, b = np.triu_indices(len(chosen), k=1)
        keep = ~self.units.overlap[unit[a], unit[b]] & (gain[a] + gain[b] > _MIN_GAIN)
        a, b = a[keep], b[keep]
        if not len(a):
            return None
        # As the mapping keeps every limit, only the two target scales need checking: every
        # other scale only loses load.
        cpu, memory = moves.table.changes(unit, scale)
        need = tot.bandwidth + moves.table.bandwidth[unit, scale][a] \
            + moves.table.bandwidth[unit, scale][b]
        linked = self.units.linked[unit[a], unit[b]]
        if linked.any():      # a connection between the two units: count it on both mappings
            la, lb = a[linked], b[linked]
            both = np.where(self.units.members[unit[la]], scale[la][:, None], current[None, :])
            both = np.where(self.units.members[unit[lb]], scale[lb][:, None], both)
            crosses = both[:, ch.conn_pub] != both[:, ch.conn_sub]
            need[linked] = crosses @ ch.conn_bandwidth
        ok = need <= self.limit + EPS
        for k in (scale[a], scale[b]):
            ok &= tot.memory[k] + memory[a, k] + memory[b, k] <= ch.scale_memory[k] + EPS
            ok &= (k == ch.master) | (tot.cpu[k] + cpu[a, k] + cpu[b, k]
                                      <= CPU_CAPACITY_PERCENT + EPS)
        if not ok.any():
            return None
        j = int(np.argmax(np.where(ok, gain[a] + gain[b], -np.inf)))
        return self._apply(self._apply(current, unit[a[j]], scale[a[j]]), unit[b[j]], scale[b[j]])

    def best_ejection(self, current, moves: _UnitMoves, out_of_time):
        """The best move that becomes feasible once a few remote nodes go back to the master,
        chosen greedily by room freed per Perf lost (an ejection chain). The most promising
        moves are tried side by side, one ejection each per step."""
        ch, master, load = self.ch, self.ch.master, self.load
        order = np.argsort(-moves.gain, kind="stable")
        order = order[moves.gain[order] > _MIN_GAIN][:self.limits.max_ejection_tries]
        if not len(order):
            return None
        tries, nodes = np.arange(len(order)), np.arange(ch.num_nodes)
        kept = self.units.members[moves.unit[order]] | ch.pinned    # (T, N) never sent home
        trials = np.where(self.units.members[moves.unit[order]], moves.scale[order][:, None],
                          current[None, :])
        net = moves.gain[order].copy()
        flat = (tries[:, None] * ch.num_scales + trials).ravel()
        per_scale = len(order) * ch.num_scales
        cpu = load + np.bincount(flat, ch.cpu[nodes, trials].ravel(),
                                 minlength=per_scale).reshape(len(order), -1)
        memory = np.bincount(flat, np.tile(ch.memory, len(order)),
                             minlength=per_scale).reshape(len(order), -1)
        bandwidth = (trials[:, ch.conn_pub] != trials[:, ch.conn_sub]) @ ch.conn_bandwidth
        live, done = np.ones(len(order), dtype=bool), np.zeros(len(order), dtype=bool)
        for _ in range(self.limits.max_ejections):
            fits = live & (excess(ch, cpu, memory, bandwidth, self.limit) <= 0)
            done |= fits
            live &= ~fits
            if not live.any() or out_of_time():
                break
            # Each remote node of each try sent home alone: the excess it removes (on its
            # scale, the master's memory, the bandwidth), and the Perf it costs.
            cpu_at = np.take_along_axis(cpu, trials, axis=1)
            memory_at = np.take_along_axis(memory, trials, axis=1)
            cpu_out = cpu_at - ch.cpu[nodes, trials]
            memory_out = memory_at - ch.memory
            memory_home = memory[:, master][:, None] + ch.memory
            bandwidth_home = bandwidth[:, None] + self.nodes.bandwidth_to(trials, master)
            limit_mb, unit_mbps = ch.scale_memory[trials], max(self.limit, 1.0)
            freed = over(cpu_at, CPU_CAPACITY_PERCENT) - over(cpu_out, CPU_CAPACITY_PERCENT) \
                + over(memory_at, limit_mb) - over(memory_out, limit_mb) \
                + over(memory[:, master][:, None], ch.scale_memory[master]) \
                - over(memory_home, ch.scale_memory[master]) \
                + over(bandwidth[:, None], self.limit, unit_mbps) \
                - over(bandwidth_home, self.limit, unit_mbps)
            loss = ch.value[nodes, trials] - ch.value[:, master]
            candidate = live[:, None] & (trials != master) & ~kept & (freed > 1e-12)
            score = np.where(candidate, freed / np.maximum(loss, 1e-9), -np.inf)
            live &= np.isfinite(score).any(axis=1)
            t = np.flatnonzero(live)
            o = np.argmax(score[t], axis=1)          # first of the best, as in node order
            s = trials[t, o]
            cpu[t, s], memory[t, s] = cpu_out[t, o], memory_out[t, o]
            cpu[t, master] += ch.cpu[o, master]
            memory[t, master] = memory_home[t, o]
            bandwidth[t] = bandwidth_home[t, o]
            net[t] -= loss[t, o]
            trials[t, o] = master
        better = done & (net > _MIN_GAIN)
        if not better.any():
            return None
        return trials[int(np.argmax(np.where(better, net, -np.inf)))].copy()


def movable_units(ch: Characterisation):
    """What a move relocates: each non-pinned node alone; with everything it feeds, or everything
    that feeds it, through non-pinned nodes; and each connected group of them (a processing
    chain moved whole keeps its links local)."""
    movable = set(int(i) for i in np.flatnonzero(~ch.pinned))
    links = [(int(p), int(q)) for p, q in zip(ch.conn_pub, ch.conn_sub)
             if int(p) in movable and int(q) in movable and p != q]
    after = {i: {q for p, q in links if p == i} for i in movable}
    before = {i: {p for p, q in links if q == i} for i in movable}
    both = {i: after[i] | before[i] for i in movable}
    units = {(i,) for i in movable}
    for i in movable:
        for graph in (after, before, both):
            units.add(tuple(sorted(_reachable(i, graph))))
    return [list(u) for u in sorted(units, key=lambda u: (len(u), u))]


def _reachable(start, graph):
    seen, todo = {start}, [start]
    while todo:
        for j in graph[todo.pop()] - seen:
            seen.add(j)
            todo.append(j)
    return seen
