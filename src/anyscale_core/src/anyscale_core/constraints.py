"""System constraints (paper III-B-4): scale CPU capacity, network bandwidth, remote links, and
the per-connection frequency/tolerance condition tracked over time."""
from dataclasses import dataclass, field, replace
import math
from typing import Any, Dict, List, Mapping, Optional

import numpy as np

from .characterisation import Characterisation
from .model import ModelError, SystemModel
from .model_loader import is_finite_number, read_yaml

# A scale is full at 100 % of its CPU (the unit of cpu_usage and scale_load): above it, nodes
# on a remote scale return.
CPU_CAPACITY_PERCENT = 100.0
# A scale busier than this (% of its capacity, ScaleStatus.cpu_percent) runs at its limit: a
# node's CPU there is the share it got. Not 100: the agents' samples are not aligned with a
# quota's CFS periods, and a group throttled in every period still idles in the milliseconds
# between its processes' wake-ups. `anyscale profile` names such figures a share by this rule,
# and the paper allocator moves a node onto a remote scale only up to it: the band up to
# CPU_CAPACITY_PERCENT keeps a move that fills a scale from being undone at its next sample.
SATURATED_PERCENT = 90.0


@dataclass(frozen=True)
class DynamicState:
    """The dynamic parameters (paper III-B-2) at one moment."""
    bandwidth_mbps: float                      # available on the network now
    scale_load: Mapping[str, float] = field(default_factory=dict)  # % of CPU not from model nodes
    link_up: Mapping[str, bool] = field(default_factory=dict)      # per remote scale; absent = up
    # What a mapping may make cross scales beyond what already crosses: the bandwidth the link
    # has held for a while, less a margin (link_capacity.BandwidthHold). inf: no such limit (the
    # paper's).
    admit_bandwidth_mbps: float = math.inf

    @staticmethod
    def nominal(model: SystemModel) -> "DynamicState":
        """Full nominal bandwidth, idle scales, every link up."""
        return DynamicState(model.network.max_bandwidth_mbps)

    def load_vector(self, ch: Characterisation) -> np.ndarray:
        return np.array([self.scale_load.get(s, 0.0) for s in ch.scale_names])

    def up_vector(self, ch: Characterisation) -> np.ndarray:
        up = np.array([self.link_up.get(s, True) for s in ch.scale_names])
        up[ch.master] = True
        return up


def load_state(path: str, model: SystemModel) -> DynamicState:
    """Reads a state file (bandwidth_mbps, scale_load, link_up); errors name the file and key."""
    data = read_yaml(path)
    return parse_state(data, model, path)


def parse_state(data: Any, model: SystemModel, source: str = "<state>") -> DynamicState:
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ModelError(source, "", f"expected a mapping, got {type(data).__name__}")
    for key in data:
        if key not in ("bandwidth_mbps", "scale_load", "link_up"):
            raise ModelError(source, str(key), "unknown key (expected one of: bandwidth_mbps, "
                                               "scale_load, link_up)")
    bandwidth = data.get("bandwidth_mbps", model.network.max_bandwidth_mbps)
    if not is_finite_number(bandwidth) or bandwidth < 0:
        raise ModelError(source, "bandwidth_mbps", f"expected a number >= 0, got {bandwidth!r}")
    load = _per_scale(data.get("scale_load"), model, source, "scale_load",
                      lambda v: isinstance(v, (int, float)) and not isinstance(v, bool)
                      and 0 <= v <= 100, "a number from 0 to 100")
    up = _per_scale(data.get("link_up"), model, source, "link_up",
                    lambda v: isinstance(v, bool), "true or false")
    if model.master.name in up:
        raise ModelError(source, f"link_up.{model.master.name}",
                         "the master scale has no link to itself; name remote scales only")
    return DynamicState(float(bandwidth), {k: float(v) for k, v in load.items()}, up)


def _per_scale(value, model, source, key, valid, expected) -> Dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ModelError(source, key, f"expected a mapping of scale names, got "
                                      f"{type(value).__name__}")
    for scale, v in value.items():
        if scale not in model.scale_names:
            raise ModelError(source, f"{key}.{scale}", f"unknown scale '{scale}' "
                                                       f"(scales: {', '.join(model.scale_names)})")
        if not valid(v):
            raise ModelError(source, f"{key}.{scale}", f"expected {expected}, got {v!r}")
    return dict(value)


def required_bandwidth(ch: Characterisation, assign: np.ndarray) -> float:
    """Mbit/s of every connection whose two ends run on different scales."""
    crosses = assign[ch.conn_pub] != assign[ch.conn_sub]
    return float(ch.conn_bandwidth[crosses].sum())


def admission_state(ch: Characterisation, assign: np.ndarray,
                    state: DynamicState) -> DynamicState:
    """The state a decision from `assign` is judged in: a mapping may need as much bandwidth as
    the link has now, but more than `assign` already needs only up to what the link has held
    (admit_bandwidth_mbps). So a node that is out stays while the link carries it, and a node
    moves out only onto a link that has shown it can carry the stream, with a margin."""
    limit = min(state.bandwidth_mbps,
                max(state.admit_bandwidth_mbps, required_bandwidth(ch, assign)))
    return replace(state, bandwidth_mbps=limit)


def scale_cpu(ch: Characterisation, assign: np.ndarray, load: np.ndarray) -> np.ndarray:
    """(K,) % CPU each scale would run at: its background load plus the nodes mapped to it."""
    used = np.bincount(assign, weights=ch.cpu[np.arange(ch.num_nodes), assign],
                       minlength=ch.num_scales)
    return load + used


def scale_memory(ch: Characterisation, assign: np.ndarray) -> np.ndarray:
    return np.bincount(assign, weights=ch.memory, minlength=ch.num_scales)


@dataclass(frozen=True)
class Violation:
    kind: str            # "placement", "link", "cpu", "memory", "bandwidth"
    message: str
    scale: Optional[str] = None


def violations(ch: Characterisation, assign: np.ndarray, state: DynamicState) -> List[Violation]:
    """Every constraint the mapping breaks under the state. The master scale is exempt from the
    CPU limit: it is where everything returns to, and it degrades to the minimum frequencies
    instead of failing (paper IV: the robot sustains only the minimum values)."""
    found = []
    names = ch.scale_names
    wrong = ~ch.allowed[np.arange(ch.num_nodes), assign]
    for i in np.flatnonzero(wrong):
        found.append(Violation("placement", f"node {ch.node_names[i]} may not run on "
                                            f"{names[assign[i]]}", names[assign[i]]))
    used = np.bincount(assign, minlength=ch.num_scales) > 0
    up = state.up_vector(ch)
    cpu = scale_cpu(ch, assign, state.load_vector(ch))
    mem = scale_memory(ch, assign)
    for k in range(ch.num_scales):
        if k == ch.master or not used[k]:
            continue
        if not up[k]:
            found.append(Violation("link", f"link to {names[k]} is down", names[k]))
        if cpu[k] > CPU_CAPACITY_PERCENT + 1e-9:
            found.append(Violation("cpu", f"{names[k]} CPU {cpu[k]:.1f} % > 100 %", names[k]))
        if mem[k] > ch.scale_memory[k] + 1e-9:
            found.append(Violation("memory", f"{names[k]} memory {mem[k]:g} MB > "
                                             f"{ch.scale_memory[k]:g} MB", names[k]))
    need = required_bandwidth(ch, assign)
    if need > state.bandwidth_mbps + 1e-9:
        found.append(Violation("bandwidth", f"bandwidth {state.bandwidth_mbps:.2f} Mbit/s < "
                                            f"{need:.2f} Mbit/s needed"))
    return found


def feasible_many(ch: Characterisation, assigns: np.ndarray, state: DynamicState) -> np.ndarray:
    """(S,) bool: each mapping respects memory, remote CPU, bandwidth and links (placement is the
    caller's: trials only use scales candidate_scales allows)."""
    ok = np.ones(len(assigns), dtype=bool)
    load = state.load_vector(ch)
    up = state.up_vector(ch)
    cpu = ch.cpu[np.arange(ch.num_nodes), assigns]
    for k in range(ch.num_scales):
        on_k = assigns == k
        ok &= (on_k * ch.memory).sum(axis=1) <= ch.scale_memory[k] + 1e-9
        if k != ch.master:
            used = on_k.any(axis=1)
            ok &= ~used | ((on_k * cpu).sum(axis=1) + load[k] <= CPU_CAPACITY_PERCENT + 1e-9)
            if not up[k]:
                ok &= ~used
    crosses = assigns[:, ch.conn_pub] != assigns[:, ch.conn_sub]
    ok &= crosses @ ch.conn_bandwidth <= state.bandwidth_mbps + 1e-9
    return ok


def is_feasible(ch: Characterisation, assign: np.ndarray, state: DynamicState) -> bool:
    return not violations(ch, assign, state)


class FrequencyToleranceTracker:
    """Tracks one connection's observed rate: a violation is the rate staying below freq_min for
    longer than the tolerance (for tolerance 0, any time below). Also tells how much tolerance is
    left, so the decision node can move a node back before it runs out."""

    def __init__(self, freq_min: float, tolerance_s: float):
        self.freq_min = freq_min
        self.tolerance_s = tolerance_s
        self._below_since: Optional[float] = None
        self._last_t: Optional[float] = None

    def update(self, t: float, rate_hz: float):
        """An observation at time t (s). A NaN rate (nothing measured) counts as below."""
        if self._last_t is not None and t < self._last_t:
            raise ValueError(f"observation at t={t} before the previous one at t={self._last_t}")
        self._last_t = t
        below = not (rate_hz >= self.freq_min)
        if not below:
            self._below_since = None
        elif self._below_since is None:
            self._below_since = t

    def below_for(self, t: float) -> float:
        """Seconds the rate has been below freq_min at time t (0 if it is not)."""
        return 0.0 if self._below_since is None else max(0.0, t - self._below_since)

    def used_fraction(self, t: float) -> float:
        """Share of the tolerance already spent below freq_min (1 for tolerance 0 when below)."""
        if self._below_since is None:
            return 0.0
        if self.tolerance_s == 0:
            return 1.0
        return min(1.0, self.below_for(t) / self.tolerance_s)

    def violated(self, t: float) -> bool:
        if self._below_since is None:
            return False
        return self.tolerance_s == 0 or self.below_for(t) > self.tolerance_s
