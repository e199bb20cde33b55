"""`paper_local`: the paper's heuristic (Algorithm 1 to its fixpoint), then improved by local search
that keeps every constraint: moves of one node or one chain of connected nodes, pairs of such
moves (swaps included), and a move made room for by sending a few remote nodes back.

Algorithm 1 places nodes greedily by CPU usage; when bandwidth or a scale's CPU binds, the greedy
order can leave much of Eq. 1 unused (bench_allocator_quality.py). A pair move lets one node make
room for another (out of a scale or off the network), which single moves cannot; moving a chain
of connected nodes together keeps the traffic between them off the network.
"""
import numpy as np

from ..characterisation import Characterisation
from ..constraints import (CPU_CAPACITY_PERCENT, DynamicState, admission_state, feasible_many,
                           is_feasible)
from .base import AllocationContext, Decision, candidate_scales, moves_between
from .paper import PaperAllocator

# Improvements smaller than this are rounding, not worth a migration.
_MIN_GAIN = 1e-6


class PaperLocalAllocator:
    name = "paper_local"

    def __init__(self, max_pair_moves: int = 120, max_rounds: int = 200,
                 max_ejection_tries: int = 20, max_ejections: int = 10):
        self.max_pair_moves = max_pair_moves   # single moves combined into pairs, at most
        self.max_rounds = max_rounds
        self.max_ejection_tries = max_ejection_tries   # best moves tried with ejections
        self.max_ejections = max_ejections             # nodes sent back to make room, at most

    def decide(self, ch: Characterisation, assign: np.ndarray, state: DynamicState,
               ctx: AllocationContext) -> Decision:
        current = PaperAllocator().decide(ch, assign, state, ctx).assign
        state = admission_state(ch, assign, state)
        if is_feasible(ch, current, state):
            mask = candidate_scales(ch, state, ctx)
            units = movable_units(ch)
            for _ in range(self.max_rounds):
                targets = _unit_moves(ch, current, mask, units)
                better = self._best_single(ch, current, state, targets)
                if better is None:
                    better = self._best_pair(ch, current, state, targets)
                if better is None:
                    better = self._best_ejection(ch, current, state, targets)
                if better is None:
                    break
                current = better
        return Decision(current, moves_between(ch, assign, current, "higher Perf (local search)",
                                               "constraints (paper, then local search)"))

    # One decision period: the search converges within the period.
    step = decide

    @staticmethod
    def _best_single(ch, current, state, targets):
        gain = _gains(ch, current, targets)
        keep = gain > _MIN_GAIN
        return _best_feasible(ch, _apply(current, targets[keep]), gain[keep], state)

    def _best_pair(self, ch, current, state, targets):
        if len(targets) < 2:
            return None
        gain = _gains(ch, current, targets)
        if len(targets) > self.max_pair_moves:
            # Half the most promising moves, half the cheapest ways to free room (moves back).
            half = self.max_pair_moves // 2
            order = np.argsort(-gain, kind="stable")
            to_master = ((targets[order] == ch.master) | (targets[order] < 0)).all(axis=1)
            back = order[to_master][:half]
            ahead = order[~np.isin(order, back)][:self.max_pair_moves - len(back)]
            chosen = np.concatenate([ahead, back])
            targets, gain = targets[chosen], gain[chosen]
        a, b = np.triu_indices(len(targets), k=1)
        disjoint = ~((targets[a] >= 0) & (targets[b] >= 0)).any(axis=1)
        a, b = a[disjoint], b[disjoint]
        total = gain[a] + gain[b]
        keep = total > _MIN_GAIN
        a, b, total = a[keep], b[keep], total[keep]
        both = np.where(targets[a] >= 0, targets[a], targets[b])
        return _best_feasible(ch, _apply(current, both), total, state)

    def _best_ejection(self, ch, current, state, targets):
        """The best move that becomes feasible once a few remote nodes go back to the master,
        chosen greedily by room freed per Perf lost (an ejection chain)."""
        gain = _gains(ch, current, targets)
        order = [j for j in np.argsort(-gain, kind="stable") if gain[j] > _MIN_GAIN]
        best, best_gain = None, _MIN_GAIN
        for j in order[:self.max_ejection_tries]:
            trial = _apply(current, targets[j][None, :])[0]
            moved = targets[j] >= 0
            for _ in range(self.max_ejections):
                excess = overload(ch, trial[None, :], state)[0]
                if excess <= 0:
                    net = _gains(ch, current, np.where(trial != current, trial, -1)[None, :])[0]
                    if net > best_gain:
                        best, best_gain = trial, net
                    break
                out = np.flatnonzero((trial != ch.master) & ~ch.pinned & ~moved)
                if not len(out):
                    break
                trials = np.repeat(trial[None, :], len(out), axis=0)
                trials[np.arange(len(out)), out] = ch.master
                freed = excess - overload(ch, trials, state)
                loss = ch.value[out, trial[out]] - ch.value[out, ch.master]
                score = np.where(freed > 1e-12, freed / np.maximum(loss, 1e-9), -np.inf)
                if not np.isfinite(score).any():
                    break
                trial = trials[int(np.argmax(score))]
        return None if best is None else best.copy()


def overload(ch: Characterisation, assigns: np.ndarray, state: DynamicState) -> np.ndarray:
    """(S,) how far each mapping exceeds the bandwidth, remote CPU and memory limits, each as a
    share of the limit (0 = within every limit; links and placement are not counted)."""
    load = state.load_vector(ch)
    cpu = ch.cpu[np.arange(ch.num_nodes), assigns]
    total = np.zeros(len(assigns))
    for k in range(ch.num_scales):
        on_k = assigns == k
        total += np.maximum(0, (on_k * ch.memory).sum(axis=1) - ch.scale_memory[k]) \
            / ch.scale_memory[k]
        if k != ch.master:
            total += np.maximum(0, (on_k * cpu).sum(axis=1) + load[k] - CPU_CAPACITY_PERCENT) \
                / CPU_CAPACITY_PERCENT
    crosses = assigns[:, ch.conn_pub] != assigns[:, ch.conn_sub]
    need = crosses @ ch.conn_bandwidth
    return total + np.maximum(0, need - state.bandwidth_mbps) / max(state.bandwidth_mbps, 1.0)


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


def _unit_moves(ch, current, mask, units) -> np.ndarray:
    """(U, N) new scale per node for every unit move to a scale all its nodes may use now,
    -1 for nodes the move leaves alone."""
    rows = []
    for unit in units:
        for k in np.flatnonzero(mask[unit].all(axis=0)):
            if (current[unit] != k).any():
                row = -np.ones(ch.num_nodes, dtype=np.int64)
                row[unit] = k
                rows.append(row)
    return np.array(rows, dtype=np.int64).reshape(-1, ch.num_nodes)


def _gains(ch, current, targets) -> np.ndarray:
    """Eq. 1 gain of each unit move."""
    moved = np.where(targets >= 0, targets, current[None, :])
    rows = np.arange(ch.num_nodes)
    return ch.value[rows, moved].sum(axis=1) - ch.value[rows, current].sum()


def _apply(current, targets) -> np.ndarray:
    return np.where(targets >= 0, targets, current[None, :])


def _best_feasible(ch, trials, gain, state):
    """The trial mapping of highest gain that keeps every constraint, or None."""
    if not len(trials):
        return None
    ok = feasible_many(ch, trials, state)
    if not ok.any():
        return None
    return trials[int(np.argmax(np.where(ok, gain, -np.inf)))].copy()
