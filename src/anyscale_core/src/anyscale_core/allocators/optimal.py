"""The exact allocator: the feasible mapping of highest Perf (Eq. 1) under the current state.

Small spaces are enumerated in numpy; larger ones are solved as a MILP with scipy.optimize.milp
(HiGHS) under a time limit. Ties go to the mapping with the fewest moves from the current one,
so an unchanged situation never causes a migration.
"""
import numpy as np
from scipy import sparse
from scipy.optimize import Bounds, LinearConstraint, milp

from ..characterisation import Characterisation, enumerate_mappings
from ..constraints import CPU_CAPACITY_PERCENT, DynamicState, admission_state, feasible_many
from ..cost import perf_of_many
from .base import AllocationContext, Decision, candidate_scales, moves_between

# Worth one move: far below any real Perf difference, enough to break exact ties.
_MOVE_PENALTY = 1e-6


class OptimalAllocator:
    name = "optimal"

    def __init__(self, enumeration_limit: int = 100_000, time_limit_s: float = 2.0):
        self.enumeration_limit = enumeration_limit
        self.time_limit_s = time_limit_s
        self.last_method = ""      # "enumeration" or "milp" (for benchmarks and logs)

    def decide(self, ch: Characterisation, assign: np.ndarray, state: DynamicState,
               ctx: AllocationContext) -> Decision:
        state = admission_state(ch, assign, state)
        mask = candidate_scales(ch, state, ctx)
        space = np.prod(mask.sum(axis=1).astype(float))
        if space <= self.enumeration_limit:
            self.last_method = "enumeration"
            best = self._enumerate(ch, assign, state, mask)
        else:
            self.last_method = "milp"
            best = self._milp(ch, assign, state, mask)
        if best is None:      # nothing feasible (e.g. pinned nodes alone exceed bandwidth)
            best = np.where(ch.pinned, assign, ch.master)
        return Decision(best, moves_between(ch, assign, best, "higher Perf (optimal)",
                                            "constraints (optimal)"))

    # One decision period: the optimum is reached in one step.
    step = decide

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

    def _milp(self, ch, assign, state, mask):
        n, k_count = ch.num_nodes, ch.num_scales
        pairs = np.argwhere(mask)                       # variable v <-> (node, scale)
        nv = len(pairs)
        var = -np.ones((n, k_count), dtype=np.int64)
        var[pairs[:, 0], pairs[:, 1]] = np.arange(nv)
        stay = (pairs[:, 1] == assign[pairs[:, 0]])
        cost = -(ch.value[pairs[:, 0], pairs[:, 1]] - _MOVE_PENALTY * ~stay)
        rows, cols, vals, lo, hi = [], [], [], [], []

        def add_row(coeffs, lower, upper):
            r = len(lo)
            for c, v in coeffs:
                rows.append(r)
                cols.append(c)
                vals.append(v)
            lo.append(lower)
            hi.append(upper)

        for i in range(n):                              # each node on exactly one scale
            add_row([(var[i, k], 1.0) for k in np.flatnonzero(mask[i])], 1.0, 1.0)
        load = state.load_vector(ch)
        for k in range(k_count):
            on_k = np.flatnonzero(mask[:, k])
            add_row([(var[i, k], ch.memory[i]) for i in on_k], -np.inf, ch.scale_memory[k])
            if k != ch.master:
                add_row([(var[i, k], ch.cpu[i, k]) for i in on_k], -np.inf,
                        CPU_CAPACITY_PERCENT - load[k])
        # y_c >= x[p,k] - x[s,k] for every k: y_c is 1 when the connection crosses scales.
        carried = np.flatnonzero(ch.conn_bandwidth > 0)
        ny = len(carried)
        for j, c in enumerate(carried):
            p, s = ch.conn_pub[c], ch.conn_sub[c]
            for k in np.flatnonzero(mask[p]):
                coeffs = [(nv + j, 1.0), (var[p, k], -1.0)]
                if var[s, k] >= 0:
                    coeffs.append((var[s, k], 1.0))
                add_row(coeffs, 0.0, np.inf)
        add_row([(nv + j, ch.conn_bandwidth[c]) for j, c in enumerate(carried)], -np.inf,
                state.bandwidth_mbps)
        a = sparse.csr_matrix((vals, (rows, cols)), shape=(len(lo), nv + ny))
        res = milp(np.concatenate([cost, np.zeros(ny)]),
                   integrality=np.concatenate([np.ones(nv), np.zeros(ny)]),
                   bounds=Bounds(0, 1), constraints=LinearConstraint(a, lo, hi),
                   options={"time_limit": self.time_limit_s})
        if res.x is None:
            return None
        chosen = res.x[:nv] > 0.5
        best = assign.copy()
        best[pairs[chosen, 0]] = pairs[chosen, 1]
        return best
