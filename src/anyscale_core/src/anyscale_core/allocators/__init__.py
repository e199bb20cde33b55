"""Allocators behind one interface: step(ch, assign, state, ctx) -> Decision is one decision
period's work (one iteration of the paper's loop); decide(...) is the converged decision."""
from .base import AllocationContext, Decision, Move, candidate_scales
from .local import PaperLocalAllocator
from .optimal import OptimalAllocator
from .paper import PaperAllocator

ALLOCATORS = {
    PaperAllocator.name: PaperAllocator,
    OptimalAllocator.name: OptimalAllocator,
    PaperLocalAllocator.name: PaperLocalAllocator,
}


def make_allocator(name: str):
    """The allocator called `name`; ValueError naming the known ones otherwise."""
    try:
        return ALLOCATORS[name]()
    except KeyError:
        raise ValueError(f"unknown allocator '{name}' (known: {', '.join(sorted(ALLOCATORS))})") \
            from None


__all__ = ["ALLOCATORS", "AllocationContext", "Decision", "Move", "OptimalAllocator",
           "PaperAllocator", "PaperLocalAllocator", "candidate_scales", "make_allocator"]
