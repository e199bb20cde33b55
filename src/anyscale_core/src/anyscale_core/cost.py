"""The paper's cost function: Perf of one mapping (Eq. 1) and its integral over a run (Eq. 2)."""
from typing import Optional

import numpy as np

from .characterisation import Characterisation


def perf(ch: Characterisation, assign: np.ndarray) -> float:
    """Eq. 1: sum over nodes of CPU_usage(node, its scale) * alpha(its scale)."""
    return float(ch.value[np.arange(ch.num_nodes), assign].sum())


def perf_of_many(ch: Characterisation, assigns: np.ndarray) -> np.ndarray:
    """Eq. 1 for each row of an (S, N) array of mappings."""
    return ch.value[np.arange(ch.num_nodes), assigns].sum(axis=1)


class ObjectiveIntegrator:
    """Eq. 2: sum of T_map * Perf_map over a run, fed with mapping changes as they happen."""

    def __init__(self, start_time: float, start_perf: float):
        self._t = start_time
        self._perf = start_perf
        self._total = 0.0
        self.start_time = start_time

    def change(self, t: float, new_perf: float):
        """The mapping changed at time t to one whose Perf is new_perf."""
        if t < self._t:
            raise ValueError(f"mapping change at t={t} before the previous one at t={self._t}")
        self._total += (t - self._t) * self._perf
        self._t, self._perf = t, new_perf

    def total(self, t: Optional[float] = None) -> float:
        """The objective up to time t (default: the last change)."""
        t = self._t if t is None else t
        if t < self._t:
            raise ValueError(f"objective asked at t={t} before the last change at t={self._t}")
        return self._total + (t - self._t) * self._perf

    def mean_perf(self, t: float) -> float:
        """Time-weighted mean Perf since the start."""
        elapsed = t - self.start_time
        return self.total(t) / elapsed if elapsed > 0 else self._perf
