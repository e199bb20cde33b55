"""The exact allocator: the feasible mapping of highest Perf (Eq. 1) under the current state.

Small spaces are enumerated in numpy. Larger ones are solved as a MILP with scipy.optimize.milp
(HiGHS), warm-started: paper_local's search from the current mapping gives the incumbent within
the time budget, the MILP gets the time it leaves, and the better of the two is the decision. So
past the size the MILP solves within the budget the decision is paper_local's, in time, rather
than the optimum, late (HiGHS can overrun its limit by its set-up). Ties go to the mapping with
the fewest moves from the current one, so an unchanged situation never causes a migration.
(scipy's milp takes no starting solution, so the incumbent competes with the MILP's instead.)
"""
import time
from typing import Callable, Optional

import numpy as np
from scipy import sparse
from scipy.optimize import Bounds, LinearConstraint, milp

from ..characterisation import enumerate_mappings
from ..constraints import (CPU_CAPACITY_PERCENT, DynamicState, admission_state, feasible_many,
                           is_feasible)
from ..cost import perf, perf_of_many
from .base import (DEFAULT_TIME_BUDGET_S, AllocationContext, Decision, Deadline,
                   candidate_scales, moves_between)
from .local import PaperLocalAllocator

# Worth one move: far below any real Perf difference, enough to break exact ties.
_MOVE_PENALTY = 1e-6
# A MILP given less time than this cannot even be set up: the incumbent stands.
_MIN_MILP_S = 1e-3


class OptimalAllocator:
    name = "optimal"

    def __init__(self, enumeration_limit: int = 100_000,
                 time_budget_s: Optional[float] = DEFAULT_TIME_BUDGET_S,
                 clock: Callable[[], float] = time.monotonic):
        self.enumeration_limit = enumeration_limit
        self.time_budget_s = time_budget_s     # s per decision beyond enumeration; None: exact
        self.clock = clock
        # "enumeration", "milp", or "local search" (the MILP found nothing better in time)
        self.last_method = ""

    def decide(self, ch, assign: np.ndarray, state: DynamicState,
               ctx: AllocationContext) -> Decision:
        out_of_time = Deadline(self.time_budget_s, self.clock)
        admitted = admission_state(ch, assign, state)
        mask = candidate_scales(ch, admitted, ctx)
        space = np.prod(mask.sum(axis=1).astype(float))
        if space <= self.enumeration_limit:
            self.last_method = "enumeration"
            best = self._enumerate(ch, assign, admitted, mask)
        else:
            best = self._warm_milp(ch, assign, state, admitted, ctx, mask, out_of_time)
        if best is None:      # nothing feasible (e.g. pinned nodes alone exceed bandwidth)
            best = np.where(ch.pinned, assign, ch.master)
        return Decision(best, moves_between(ch, assign, best, "higher Perf (optimal)",
                                            "constraints (optimal)"))

    # One decision period: the optimum (or the best found in the budget) in one step.
    step = decide

    def _warm_milp(self, ch, assign, state, admitted, ctx, mask, out_of_time):
        incumbent = PaperLocalAllocator(time_budget_s=out_of_time.left(), clock=self.clock
                                        ).decide(ch, assign, state, ctx).assign
        left = out_of_time.left()
        solved = None
        if left is None or left >= _MIN_MILP_S:
            solved = self._milp(ch, assign, admitted, mask, left)
        # Either may break a limit: the incumbent where Algorithm 1 alone could not keep them
        # all, the MILP's solution by the solver's tolerances.
        incumbent, solved = (a if a is not None and is_feasible(ch, a, admitted) else None
                             for a in (incumbent, solved))
        score = {name: perf(ch, a) - _MOVE_PENALTY * (a != assign).sum()
                 for name, a in (("milp", solved), ("local search", incumbent)) if a is not None}
        if not score:
            self.last_method = "milp"
            return None
        self.last_method = max(score, key=lambda name: (score[name], name == "milp"))
        return solved if self.last_method == "milp" else incumbent

    @staticmethod
    def _enumerate(ch, assign, state, mask):
        assigns = enumerate_mappings(ch, mask)
        if len(assigns) == 0:
            return None
        ok = feasible_many(ch, assigns, state)
        if not ok.any():
            return None
        score = perf_of_many(ch, assigns) - _MOVE_PENALTY * (assigns != assign).sum(axis=1)
        score[~ok] = -np.inf
        return assigns[int(np.argmax(score))].copy()

    @staticmethod
    def _milp(ch, assign, state, mask, time_limit_s: Optional[float]):
        n, k_count = ch.num_nodes, ch.num_scales
        pairs = np.argwhere(mask)                       # variable v <-> (node, scale)
        nv = len(pairs)
        node, scale = pairs[:, 0], pairs[:, 1]
        var = -np.ones((n, k_count), dtype=np.int64)
        var[node, scale] = np.arange(nv)
        cost = -(ch.value[node, scale] - _MOVE_PENALTY * (scale != assign[node]))
        blocks = []           # (rows, cols, values) of each group of constraint rows
        lo, hi = [], []

        def add(rows, cols, vals, lower, upper):
            blocks.append((np.asarray(rows) + len(lo), cols, vals))
            lo.extend(lower)
            hi.extend(upper)

        # Each node on exactly one scale.
        add(node, np.arange(nv), np.ones(nv), np.ones(n), np.ones(n))
        # Memory on every scale, CPU on every remote one.
        add(scale, np.arange(nv), ch.memory[node], np.full(k_count, -np.inf), ch.scale_memory)
        remote = np.flatnonzero(scale != ch.master)
        remote_row = np.cumsum(np.arange(k_count) != ch.master) - 1    # scale -> its CPU row
        load = state.load_vector(ch)
        add(remote_row[scale[remote]], remote, ch.cpu[node[remote], scale[remote]],
            np.full(k_count - 1, -np.inf),
            np.delete(CPU_CAPACITY_PERCENT - load, ch.master))
        # y_c >= x[p,k] - x[s,k] for every k: y_c is 1 when connection c crosses scales.
        carried = np.flatnonzero(ch.conn_bandwidth > 0)
        ny = len(carried)
        j, k = np.nonzero(mask[ch.conn_pub[carried]])   # (carried conn j, a scale of its pub)
        rows = np.arange(len(j))
        x_sub = var[ch.conn_sub[carried][j], k]
        has_sub = x_sub >= 0
        add(np.concatenate([rows, rows, rows[has_sub]]),
            np.concatenate([nv + j, var[ch.conn_pub[carried][j], k], x_sub[has_sub]]),
            np.concatenate([np.ones(len(j)), -np.ones(len(j)), np.ones(int(has_sub.sum()))]),
            np.zeros(len(j)), np.full(len(j), np.inf))
        add(np.zeros(ny, dtype=np.int64), nv + np.arange(ny), ch.conn_bandwidth[carried],
            [-np.inf], [state.bandwidth_mbps])
        rows, cols, vals = (np.concatenate([b[i] for b in blocks]) for i in range(3))
        a = sparse.csr_matrix((vals, (rows, cols)), shape=(len(lo), nv + ny))
        options = {} if time_limit_s is None else {"time_limit": time_limit_s}
        res = milp(np.concatenate([cost, np.zeros(ny)]),
                   integrality=np.concatenate([np.ones(nv), np.zeros(ny)]),
                   bounds=Bounds(0, 1), constraints=LinearConstraint(a, lo, hi),
                   options=options)
        if res.x is None:
            return None
        chosen = res.x[:nv] > 0.5
        best = assign.copy()
        best[node[chosen]] = scale[chosen]
        return best
