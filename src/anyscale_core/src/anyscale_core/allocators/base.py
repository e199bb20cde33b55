"""What every allocator takes and returns, and the scales a node may move to right now."""
from dataclasses import dataclass, field
from typing import AbstractSet, Callable, List, Mapping, Optional, Tuple

import numpy as np

from ..characterisation import Characterisation
from ..constraints import CPU_CAPACITY_PERCENT, DynamicState


# s a decision of a searching allocator (paper_local, optimal at fleet size) may take: a tenth
# of the decision node's default period (~period_s), so a late decision does not delay the next.
DEFAULT_TIME_BUDGET_S = 0.1


class Deadline:
    """Called: whether the budget, counted from construction, has run out (never, for None)."""

    def __init__(self, budget_s: Optional[float], clock: Callable[[], float]):
        self._clock = clock
        self._end = None if budget_s is None else clock() + budget_s

    def __call__(self) -> bool:
        return self._end is not None and self._clock() >= self._end

    def left(self) -> Optional[float]:
        """Seconds left (>= 0), or None without a budget."""
        return None if self._end is None else max(0.0, self._end - self._clock())


@dataclass(frozen=True)
class AllocationContext:
    """Explicit decision state, so allocators are pure functions of their inputs."""
    now: float = 0.0                               # s
    hysteresis_s: float = 0.0                      # the paper's T
    migrated_back_at: Mapping[int, float] = field(default_factory=dict)  # node -> time (s)
    # node -> which of its connections spends its tolerance, and how (for the reason)
    violating: Mapping[int, str] = field(default_factory=dict)
    # nodes the link lost less than their hold after a loss ago (DecisionParams.hold_after_loss)
    held_after_loss: AbstractSet[int] = frozenset()
    # (node, scale) moves a failed placement's back-off holds back (placement_backoff.py)
    blocked: AbstractSet[Tuple[int, int]] = frozenset()

    def held_on_master(self, i: int) -> bool:
        """Node i may not leave the master: it violates, the link was lost less than its hold
        after a loss ago, or it came back less than T ago."""
        if i in self.violating or i in self.held_after_loss:
            return True
        t = self.migrated_back_at.get(i)
        return t is not None and self.now - t < self.hysteresis_s


@dataclass(frozen=True)
class Move:
    node: int
    source: int
    target: int
    reason: str


@dataclass(frozen=True)
class Decision:
    assign: np.ndarray             # (N,) scale index per node
    moves: List[Move]              # what changed from the mapping the allocator was given


def candidate_scales(ch: Characterisation, state: DynamicState,
                     ctx: AllocationContext) -> np.ndarray:
    """(N, K) bool: where each node could run now, judged node by node (static allowance, link
    up, held nodes on the master, room for the node alone). Combined limits are the caller's."""
    mask = ch.allowed & state.up_vector(ch)[None, :]
    load = state.load_vector(ch)
    fits_alone = (ch.cpu + load[None, :] <= CPU_CAPACITY_PERCENT + 1e-9)
    fits_alone[:, ch.master] = True
    mask &= fits_alone & (ch.memory[:, None] <= ch.scale_memory[None, :])
    mask[ch.pinned] = ch.allowed[ch.pinned]
    named = set(ctx.violating) | set(ctx.held_after_loss) | set(ctx.migrated_back_at)
    held = [i for i in named if not ch.pinned[i] and ctx.held_on_master(i)]
    mask[held] = False
    mask[held, ch.master] = True
    for i, k in ctx.blocked:
        mask[i, k] = False
    return mask


def moves_between(ch: Characterisation, before: np.ndarray, after: np.ndarray,
                  reason_out: str, reason_back: str) -> List[Move]:
    changed = np.flatnonzero(before != after)
    return [Move(int(i), int(before[i]), int(after[i]),
                 reason_back if after[i] == ch.master else reason_out) for i in changed]
