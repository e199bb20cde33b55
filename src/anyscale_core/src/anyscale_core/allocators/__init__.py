"""Allocators behind one interface: step(ch, assign, state, ctx) -> Decision is one decision
period's work (one iteration of the paper's loop); decide(...) is the converged decision."""
from typing import Optional

from .base import DEFAULT_TIME_BUDGET_S, AllocationContext, Decision, Move, candidate_scales
from .local import PaperLocalAllocator
from .optimal import OptimalAllocator
from .paper import PaperAllocator

ALLOCATORS = {
    PaperAllocator.name: PaperAllocator,
    OptimalAllocator.name: OptimalAllocator,
    PaperLocalAllocator.name: PaperLocalAllocator,
}
# The allocator the decision node and `anyscale plan` use unless told otherwise.
DEFAULT_ALLOCATOR = PaperAllocator.name
# The allocators that search, and so take a time budget; Algorithm 1's step is one move.
BUDGETED = (PaperLocalAllocator.name, OptimalAllocator.name)


def make_allocator(name: str, time_budget_s: Optional[float] = DEFAULT_TIME_BUDGET_S):
    """The allocator called `name`; one that searches returns its best decision found within
    about time_budget_s (None: no limit). ValueError naming the known ones otherwise."""
    try:
        cls = ALLOCATORS[name]
    except KeyError:
        raise ValueError(f"unknown allocator '{name}' (known: {', '.join(sorted(ALLOCATORS))})") \
            from None
    return cls(time_budget_s=time_budget_s) if name in BUDGETED else cls()


__all__ = ["ALLOCATORS", "BUDGETED", "DEFAULT_ALLOCATOR", "DEFAULT_TIME_BUDGET_S",
           "AllocationContext", "Decision", "Move", "OptimalAllocator", "PaperAllocator",
           "PaperLocalAllocator", "candidate_scales", "make_allocator"]
