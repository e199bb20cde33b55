"""Algorithm 1 of the paper (dynamic node allocation), one loop iteration per step().

Where the published pseudo-code is ambiguous this follows its evident intent, as noted inline:
- `select_right` (which migrated node goes back) returns, in order, nodes on a scale whose link
  is down, nodes on a violating connection, nodes on an overloaded scale, then the node whose
  return frees the most bandwidth;
- a candidate node that fails the hysteresis or bandwidth test is skipped (the pseudo-code has
  no else branch and would spin on it);
- the bandwidth test is made on the mapping as it would be after the move;
- a node moves onto a remote scale only while that keeps the scale below SATURATED_PERCENT
  (90 %), and returns for its CPU only above CPU_CAPACITY_PERCENT (100 %), so that a move that
  fills a scale is not undone at its next sample.
"""
from dataclasses import replace
from typing import List, Tuple

import numpy as np

from ..characterisation import Characterisation
from ..constraints import (CPU_CAPACITY_PERCENT, SATURATED_PERCENT, DynamicState,
                           admission_state, required_bandwidth, scale_cpu, scale_memory)
from .base import AllocationContext, Decision, Move, candidate_scales
from .move_delta import UnitDeltas


class PaperAllocator:
    """The paper's heuristic: most CPU-hungry migratable node to the fastest remote scale."""
    name = "paper"

    def step(self, ch: Characterisation, assign: np.ndarray, state: DynamicState,
             ctx: AllocationContext) -> Decision:
        """One iteration of Algorithm 1's while loop: migrate back, or migrate one node."""
        back = self._migrate_back(ch, assign, state, ctx)
        if back is not None:
            return back
        return self._migrate_one(ch, assign, state, ctx)

    def decide(self, ch: Characterisation, assign: np.ndarray, state: DynamicState,
               ctx: AllocationContext) -> Decision:
        """Steps until the mapping stops changing: the decision the loop converges to."""
        moves: List[Move] = []
        current = assign
        for _ in range(2 * ch.num_nodes + 1):
            d = self.step(ch, current, state, ctx)
            if not d.moves:
                break
            moves.extend(d.moves)
            current = d.assign
            back = {m.node for m in d.moves if m.target == ch.master}
            if back:  # what just came back stays back for T (and within this decision)
                ctx = replace(ctx, hysteresis_s=max(ctx.hysteresis_s, 1e-9),
                              migrated_back_at={**ctx.migrated_back_at,
                                                **{i: ctx.now for i in back}})
        return Decision(current, moves)

    def _migrate_back(self, ch, assign, state, ctx):
        migrated = [int(i) for i in np.flatnonzero((assign != ch.master) & ~ch.pinned)]
        if not migrated:
            return None
        forced = self._must_return(ch, assign, state, ctx, migrated)
        over_bandwidth = required_bandwidth(ch, assign) > state.bandwidth_mbps + 1e-9
        if not forced and not over_bandwidth:
            return None
        new = assign.copy()
        moves = []
        for i, reason in forced:
            moves.append(Move(i, int(new[i]), ch.master, reason))
            new[i] = ch.master
        while required_bandwidth(ch, new) > state.bandwidth_mbps + 1e-9:
            remaining = np.array([i for i in migrated if new[i] != ch.master], dtype=np.int64)
            if not len(remaining):
                break
            need = required_bandwidth(ch, new)
            # What each one's return frees: the node whose return frees the most goes.
            relief = -UnitDeltas(ch).bandwidth(new)[remaining, ch.master]
            i = int(remaining[int(np.argmax(relief))])
            moves.append(Move(i, int(new[i]), ch.master,
                              f"bandwidth {state.bandwidth_mbps:.2f} < {need:.2f} Mbit/s needed"))
            new[i] = ch.master
        return Decision(new, moves)

    @staticmethod
    def _must_return(ch, assign, state, ctx, migrated) -> List[Tuple[int, str]]:
        up = state.up_vector(ch)
        forced = {}
        for i in migrated:
            if not up[assign[i]]:
                forced[i] = f"link to {ch.scale_names[assign[i]]} down"
            elif i in ctx.violating:
                forced[i] = f"connection spending its tolerance: {ctx.violating[i]}"
        cpu = scale_cpu(ch, assign, state.load_vector(ch))
        mem = scale_memory(ch, assign)
        over = (cpu > CPU_CAPACITY_PERCENT + 1e-9) | (mem > ch.scale_memory + 1e-9)
        for k in np.flatnonzero(over):
            if k == ch.master:
                continue
            # Return the heaviest nodes of an overloaded scale until it fits again.
            here = sorted((i for i in migrated if assign[i] == k and i not in forced),
                          key=lambda i: -ch.cpu[i, k])
            for i in here:
                if cpu[k] <= CPU_CAPACITY_PERCENT + 1e-9 and mem[k] <= ch.scale_memory[k] + 1e-9:
                    break
                forced[i] = f"{ch.scale_names[k]} over capacity (CPU {cpu[k]:.0f} %)"
                cpu[k] -= ch.cpu[i, k]
                mem[k] -= ch.memory[i]
        return sorted(forced.items())

    @staticmethod
    def _migrate_one(ch, assign, state, ctx) -> Decision:
        mask = candidate_scales(ch, state, ctx)
        order = np.argsort(-ch.cpu[:, ch.master], kind="stable")
        node_list = order[(assign[order] == ch.master) & ~ch.pinned[order]
                          & (mask[order].sum(axis=1) > 1)]
        scale_list = np.array([k for k in np.argsort(-ch.cpu_ghz, kind="stable")
                               if k != ch.master], dtype=np.int64)
        if not len(node_list) or not len(scale_list):
            return Decision(assign.copy(), [])
        load = state.load_vector(ch)
        cpu = scale_cpu(ch, assign, load)
        mem = scale_memory(ch, assign)
        bandwidth = admission_state(ch, assign, state).bandwidth_mbps
        need = required_bandwidth(ch, assign) \
            + UnitDeltas(ch).bandwidth(assign)[np.ix_(node_list, scale_list)]
        # The first (node_i, scale_j) in the order of node_list, then scale_list, that
        # scale_j can allocate, short of running saturated, with the bandwidth the move leaves.
        fits = mask[np.ix_(node_list, scale_list)] & (need <= bandwidth + 1e-9) \
            & (cpu[scale_list] + ch.cpu[np.ix_(node_list, scale_list)]
               <= SATURATED_PERCENT + 1e-9) \
            & (mem[scale_list] + ch.memory[node_list][:, None]
               <= ch.scale_memory[scale_list] + 1e-9)
        if not fits.any():
            return Decision(assign.copy(), [])
        row, col = divmod(int(np.argmax(fits.ravel())), len(scale_list))
        i, k = int(node_list[row]), int(scale_list[col])
        trial = assign.copy()
        trial[i] = k
        return Decision(trial, [Move(i, int(assign[i]), k, f"{ch.scale_names[k]} can take it "
                                                           f"({ch.cpu[i, k]:.0f} % CPU there)")])
