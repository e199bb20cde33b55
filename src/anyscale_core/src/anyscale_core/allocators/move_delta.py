"""What moving a group of nodes changes, from the mapping's totals instead of by rebuilding and
re-checking each trial mapping: Eq. 1's gain, each scale's CPU and memory, and the bandwidth
crossing scales. This is what keeps the allocators' searches fast at N=200, K=20;
test_move_delta.py checks every delta against the full recomputation."""
from dataclasses import dataclass
from functools import cached_property
from typing import Optional

import numpy as np
from scipy import sparse

from ..characterisation import Characterisation
from ..constraints import CPU_CAPACITY_PERCENT, required_bandwidth, scale_cpu, scale_memory

# The slack every constraint check in constraints.py allows.
EPS = 1e-9


@dataclass(frozen=True)
class Totals:
    """What one mapping uses: per scale (K,) CPU % with the background load and memory MB;
    and the Mbit/s crossing scales."""
    cpu: np.ndarray
    memory: np.ndarray
    bandwidth: float


def totals_of(ch: Characterisation, assign: np.ndarray, load: np.ndarray) -> Totals:
    return Totals(scale_cpu(ch, assign, load), scale_memory(ch, assign),
                  required_bandwidth(ch, assign))


def over(value, limit, unit=None):
    """How far value exceeds limit, as a share of `unit` (default: the limit); 0 within it."""
    return np.maximum(0, value - limit) / (limit if unit is None else unit)


def excess(ch: Characterisation, cpu, memory, bandwidth, limit_mbps) -> np.ndarray:
    """How far totals exceed the memory, remote CPU and bandwidth limits, each as a share of
    its limit, summed (0 = within all of them); over the leading dimensions of (..., K)."""
    remote = np.arange(ch.num_scales) != ch.master
    return over(memory, ch.scale_memory).sum(axis=-1) \
        + (over(cpu, CPU_CAPACITY_PERCENT) * remote).sum(axis=-1) \
        + over(bandwidth, limit_mbps, max(limit_mbps, 1.0))


@dataclass(frozen=True)
class UnitTable:
    """(U, K) for unit u (a group of nodes) moved whole to scale k from one mapping: `gain`
    (Eq. 1); what enters k: `cpu` (% of k), `memory` (MB), `count` (nodes; 0 = all already
    there); `bandwidth`: the change of the Mbit/s crossing scales. And (U, K) what leaves each
    scale k when the unit moves elsewhere: `cpu_out`, `memory_out`."""
    gain: np.ndarray
    cpu: np.ndarray
    memory: np.ndarray
    count: np.ndarray
    bandwidth: np.ndarray
    cpu_out: np.ndarray
    memory_out: np.ndarray

    def changes(self, unit: np.ndarray, scale: np.ndarray):
        """(R, K) change of every scale's cpu and memory for the moves unit[r] -> scale[r] (the
        unit's nodes already on that scale stay)."""
        rows = np.arange(len(unit))
        out = []
        for into, leaving in ((self.cpu, self.cpu_out), (self.memory, self.memory_out)):
            change = -leaving[unit]
            change[rows, scale] = into[unit, scale]
            out.append(change)
        return tuple(out)


class UnitDeltas:
    """The deltas of moving fixed groups of nodes on one characterisation, for any mapping:
    `members` (U, N) bool gives the groups (units); None, each node alone (row i = node i)."""

    def __init__(self, ch: Characterisation, members: Optional[np.ndarray] = None):
        self.ch = ch
        pub, sub = ch.conn_pub, ch.conn_sub
        if members is None:
            self.num_units = ch.num_nodes
            self._unit = self._node = np.arange(ch.num_nodes)   # one entry per membership
            # Connections with one end in a unit (unit, connection, node at the other end)
            # and with both ends in it (unit, connection).
            apart = np.flatnonzero(pub != sub)
            self._one_unit = np.concatenate([pub[apart], sub[apart]])
            self._one_conn = np.concatenate([apart, apart])
            self._one_other = np.concatenate([sub[apart], pub[apart]])
            self._both_conn = np.flatnonzero(pub == sub)
            self._both_unit = pub[self._both_conn]
        else:
            self.members = members = np.asarray(members, dtype=bool)
            self.num_units = len(members)
            self._unit, self._node = np.nonzero(members)
            pub_in, sub_in = members[:, pub], members[:, sub]
            self._one_unit, self._one_conn = np.nonzero(pub_in != sub_in)
            self._one_other = np.where(pub_in[self._one_unit, self._one_conn],
                                       sub[self._one_conn], pub[self._one_conn])
            self._both_unit, self._both_conn = np.nonzero(pub_in & sub_in)

    @cached_property
    def _by_node(self) -> sparse.csr_matrix:
        """(U, N) 0/1: the nodes of each unit."""
        return sparse.csr_matrix((np.ones(len(self._unit)), (self._unit, self._node)),
                                 shape=(self.num_units, self.ch.num_nodes))

    @cached_property
    def members(self) -> np.ndarray:
        """(U, N) bool: the nodes of each unit (set at once when given)."""
        return self._by_node.toarray() > 0

    @cached_property
    def overlap(self) -> np.ndarray:
        """(U, U) bool: the two units share a node."""
        return (self._by_node @ self._by_node.T).toarray() > 0

    @cached_property
    def linked(self) -> np.ndarray:
        """(U, U) bool: a connection runs between a node of one unit and a node of the other
        (their bandwidth changes do not simply add up)."""
        pub, sub = self.members[:, self.ch.conn_pub], self.members[:, self.ch.conn_sub]
        pub, sub = pub.astype(float), sub.astype(float)
        return (pub @ sub.T + sub @ pub.T) > 0

    def bandwidth(self, assign: np.ndarray) -> np.ndarray:
        """(U, K) change of the Mbit/s crossing scales when unit u moves whole to scale k."""
        ch, k, units = self.ch, self.ch.num_scales, self.num_units
        other_on = np.bincount(self._one_unit * k + assign[self._one_other],
                               ch.conn_bandwidth[self._one_conn], minlength=units * k)
        return self._bandwidth_base(assign[None, :])[0][:, None] - other_on.reshape(units, k)

    def bandwidth_to(self, assigns: np.ndarray, scale: int) -> np.ndarray:
        """(S, U) the same for moves to one scale, from each of the (S, N) mappings."""
        units, count = self.num_units, len(assigns)
        rows = np.arange(count)[:, None]
        bw = self.ch.conn_bandwidth[self._one_conn]
        other_on = np.bincount((rows * units + self._one_unit).ravel(),
                               (bw * (assigns[:, self._one_other] == scale)).ravel(),
                               minlength=count * units)
        return self._bandwidth_base(assigns) - other_on.reshape(count, units)

    def _bandwidth_base(self, assigns):
        """(S, U): the change if every connection with one end in the unit crossed after the
        move (the callers take off those whose other end is on the target)."""
        # A connection with both ends in the unit stops crossing; with one end in it, it
        # crosses after the move unless its other end is on the target scale.
        ch, units, count = self.ch, self.num_units, len(assigns)
        bw = ch.conn_bandwidth
        crossing = assigns[:, ch.conn_pub] != assigns[:, ch.conn_sub]
        rows = np.arange(count)[:, None]
        one, both = self._one_conn, self._both_conn
        base = np.bincount((rows * units + self._one_unit).ravel(),
                           (bw[one] * ~crossing[:, one]).ravel(), minlength=count * units) \
            - np.bincount((rows * units + self._both_unit).ravel(),
                          (bw[both] * crossing[:, both]).ravel(), minlength=count * units)
        return base.reshape(count, units)

    def table(self, assign: np.ndarray) -> UnitTable:
        ch, k, units = self.ch, self.ch.num_scales, self.num_units
        rows = np.arange(ch.num_nodes)

        def per_unit_scale(weights=None):
            return np.bincount(self._unit * k + assign[self._node], weights,
                               minlength=units * k).reshape(units, k)

        # Sums of differences, so a node already on k adds exactly 0 (no rounding in ties).
        gain = np.asarray(self._by_node @ (ch.value - ch.value[rows, assign][:, None]))
        cpu_out = per_unit_scale(ch.cpu[self._node, assign[self._node]])
        memory_out = per_unit_scale(ch.memory[self._node])
        cpu = np.asarray(self._by_node @ ch.cpu) - cpu_out
        memory = np.bincount(self._unit, ch.memory[self._node], minlength=units)[:, None] \
            - memory_out
        count = np.bincount(self._unit, minlength=units)[:, None] - per_unit_scale()
        return UnitTable(gain, cpu, memory, count, self.bandwidth(assign), cpu_out, memory_out)
