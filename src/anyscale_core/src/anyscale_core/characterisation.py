"""Static characterisation of a system model (paper III-B): critical, pinned and migratable nodes,
the scales each node may run on, and how many mappings remain after pruning.

The result is also the model compiled to arrays (node i, scale k) that the cost, constraint and
allocator modules work on, so that a decision at N=200, K=20 stays in numpy.
"""
from dataclasses import dataclass
import math
from typing import Dict, Optional, Tuple

import numpy as np

from .model import SystemModel

# Above this many candidate mappings the exact count with combined memory limits is not
# enumerated; the count after per-node pruning is still exact.
ENUMERATION_LIMIT = 1_000_000


@dataclass(frozen=True)
class Characterisation:
    model: SystemModel
    node_names: Tuple[str, ...]
    scale_names: Tuple[str, ...]
    master: int                      # index of the master scale
    critical: np.ndarray             # (N,) bool: on a connection with tolerance 0
    pinned: np.ndarray               # (N,) bool: must run on one scale (critical or `pinned:`)
    allowed: np.ndarray              # (N, K) bool: scale k may run node i
    cpu: np.ndarray                  # (N, K) % of scale k's CPU, 0 where not allowed
    value: np.ndarray                # (N, K) cpu * alpha: node i's term of Eq. 1 on scale k
    memory: np.ndarray               # (N,) MB
    scale_memory: np.ndarray         # (K,) MB
    cpu_ghz: np.ndarray              # (K,)
    alpha: np.ndarray                # (K,)
    conn_pub: np.ndarray             # (C,) node index of each connection's publisher
    conn_sub: np.ndarray             # (C,) node index of its subscriber
    conn_bandwidth: np.ndarray       # (C,) Mbit/s carried when it crosses scales

    @property
    def migratable(self) -> np.ndarray:
        """(N,) bool: nodes that may run on more than one scale."""
        return self.allowed.sum(axis=1) > 1

    @property
    def num_nodes(self) -> int:
        return len(self.node_names)

    @property
    def num_scales(self) -> int:
        return len(self.scale_names)

    def node_index(self, name: str) -> int:
        return self.node_names.index(name)

    def scale_index(self, name: str) -> int:
        return self.scale_names.index(name)

    def initial_mapping(self) -> np.ndarray:
        """The paper's initial configuration: every node on the master scale (a node pinned
        elsewhere on its own scale)."""
        return np.where(self.pinned, self.allowed.argmax(axis=1), self.master).astype(np.int64)

    def as_dict(self, assign: np.ndarray) -> Dict[str, str]:
        return {n: self.scale_names[k] for n, k in zip(self.node_names, assign)}

    def bandwidth_of_node(self, i: int) -> float:
        """Mbit/s that node i moves over the network when it runs apart from all its peers."""
        touches = (self.conn_pub == i) | (self.conn_sub == i)
        return float(self.conn_bandwidth[touches].sum())


def critical_node_names(model: SystemModel) -> Tuple[str, ...]:
    """Nodes on at least one connection whose tolerance is 0 (paper III-B-1)."""
    names = {c.publisher for c in model.connections if c.tolerance == 0}
    names |= {c.subscriber for c in model.connections if c.tolerance == 0}
    return tuple(n for n in model.node_names if n in names)


def characterise(model: SystemModel) -> Characterisation:
    nodes, scales = model.node_names, model.scale_names
    n, k = len(nodes), len(scales)
    master = scales.index(model.master.name)
    critical = np.array([name in critical_node_names(model) for name in nodes], dtype=bool)
    cpu = np.zeros((n, k))
    allowed = np.zeros((n, k), dtype=bool)
    pinned = critical.copy()
    scale_memory = np.array([s.memory_mb for s in model.scales])
    for i, node in enumerate(model.nodes):
        for scale, usage in node.cpu_usage.items():
            cpu[i, scales.index(scale)] = usage
            allowed[i, scales.index(scale)] = True
        # A node too big for a scale's memory on its own can never run there.
        allowed[i] &= node.memory_mb <= scale_memory
        if critical[i]:
            allowed[i] = False
            allowed[i, master] = True
        elif node.pinned is not None:
            pinned[i] = True
            only = scales.index(node.pinned)
            allowed[i] = False
            allowed[i, only] = True
    cpu = np.where(allowed, cpu, 0.0)
    alpha = np.array([s.alpha for s in model.scales])
    index = {name: i for i, name in enumerate(nodes)}
    return Characterisation(
        model=model, node_names=nodes, scale_names=scales, master=master,
        critical=critical, pinned=pinned, allowed=allowed, cpu=cpu, value=cpu * alpha,
        memory=np.array([node.memory_mb for node in model.nodes]), scale_memory=scale_memory,
        cpu_ghz=np.array([s.cpu_ghz for s in model.scales]), alpha=alpha,
        conn_pub=np.array([index[c.publisher] for c in model.connections], dtype=np.int64),
        conn_sub=np.array([index[c.subscriber] for c in model.connections], dtype=np.int64),
        conn_bandwidth=np.array([c.bandwidth_mbps for c in model.connections], dtype=float))


@dataclass(frozen=True)
class MappingCount:
    before_pruning: int               # K ** N
    after_pinning: int                # product of the scales each node may use
    after_memory: Optional[int]       # also honouring every scale's memory; None if not counted


def count_mappings(ch: Characterisation, limit: int = ENUMERATION_LIMIT) -> MappingCount:
    """How many mappings exist, and how many survive static pruning (pinned nodes, memory)."""
    choices = ch.allowed.sum(axis=1)
    after_pinning = math.prod(int(c) for c in choices)
    after_memory = None
    if after_pinning <= limit:
        assigns = enumerate_mappings(ch, ch.allowed)
        after_memory = int(memory_fits(ch, assigns).sum())
    return MappingCount(ch.num_scales ** ch.num_nodes, after_pinning, after_memory)


def enumerate_mappings(ch: Characterisation, allowed: np.ndarray) -> np.ndarray:
    """Every mapping that uses only allowed scales, as an (S, N) array of scale indices."""
    options = [np.flatnonzero(row) for row in allowed]
    if any(len(o) == 0 for o in options):
        return np.empty((0, ch.num_nodes), dtype=np.int64)
    grids = np.meshgrid(*options, indexing="ij")
    return np.stack([g.ravel() for g in grids], axis=1).astype(np.int64)


def memory_fits(ch: Characterisation, assigns: np.ndarray) -> np.ndarray:
    """(S,) bool: every scale holds the memory of the nodes mapped to it."""
    used = np.stack([(ch.memory * (assigns == k)).sum(axis=1) for k in range(ch.num_scales)],
                    axis=1)
    return (used <= ch.scale_memory).all(axis=1)
