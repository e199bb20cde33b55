"""The allocators' fast move deltas (allocators/move_delta.py) equal the full recomputation of
Eq. 1, the scale totals and the bandwidth on the mapping after the move, on random systems."""
from hypothesis import given, strategies as st
import numpy as np
import pytest

from anyscale_core.allocators.move_delta import UnitDeltas
from anyscale_core.constraints import required_bandwidth, scale_cpu, scale_memory
from anyscale_core.cost import perf

from core_test_data import random_systems


@st.composite
def systems_with_units(draw):
    """A system, a mapping of it (any scale, allowed or not: deltas do not care) and units (random
    groups of nodes, some overlapping), or None for each node alone."""
    ch = draw(random_systems())
    n, k = ch.num_nodes, ch.num_scales
    assign = np.array(draw(st.lists(st.integers(0, k - 1), min_size=n, max_size=n)))
    if draw(st.booleans()):
        return ch, assign, None
    count = draw(st.integers(1, 6))
    members = np.array(draw(st.lists(st.lists(st.booleans(), min_size=n, max_size=n),
                                     min_size=count, max_size=count)), dtype=bool)
    return ch, assign, members


def moved(assign, members, u, k):
    after = assign.copy()
    after[members[u]] = k
    return after


@given(systems_with_units())
def test_each_unit_move_delta_equals_the_recomputed_totals(case):
    ch, assign, members = case
    deltas = UnitDeltas(ch, members)
    members = deltas.members
    table = deltas.table(assign)
    load = np.zeros(ch.num_scales)
    for u in range(len(members)):
        for k in range(ch.num_scales):
            after = moved(assign, members, u, k)
            assert table.gain[u, k] == pytest.approx(perf(ch, after) - perf(ch, assign),
                                                     abs=1e-9)
            assert table.bandwidth[u, k] == pytest.approx(
                required_bandwidth(ch, after) - required_bandwidth(ch, assign), abs=1e-9)
            entering = members[u] & (assign != k)
            assert table.count[u, k] == entering.sum()
            assert table.cpu[u, k] == pytest.approx(ch.cpu[entering, k].sum(), abs=1e-9)
            assert table.memory[u, k] == pytest.approx(ch.memory[entering].sum(), abs=1e-9)
            cpu, memory = table.changes(np.array([u]), np.array([k]))
            assert cpu[0] == pytest.approx(scale_cpu(ch, after, load) - scale_cpu(ch, assign, load),
                                           abs=1e-9)
            assert memory[0] == pytest.approx(scale_memory(ch, after) - scale_memory(ch, assign),
                                              abs=1e-9)
    # The same to one scale from several mappings at once (the ejection chains' form).
    others = np.stack([assign, np.full_like(assign, ch.master), (assign + 1) % ch.num_scales])
    for k in range(ch.num_scales):
        many = deltas.bandwidth_to(others, k)
        for row, other in zip(many, others):
            assert row == pytest.approx(deltas.table(other).bandwidth[:, k], abs=1e-9)


@given(systems_with_units())
def test_units_that_share_no_node_and_no_connection_add_up(case):
    """Two disjoint units moved together change the bandwidth by the sum of their changes unless
    `linked` says a connection runs between them."""
    ch, assign, members = case
    deltas = UnitDeltas(ch, members)
    members = deltas.members
    table = deltas.table(assign)
    for u in range(len(members)):
        for v in range(u + 1, len(members)):
            assert deltas.overlap[u, v] == (members[u] & members[v]).any()
            between = (members[u][ch.conn_pub] & members[v][ch.conn_sub]) \
                | (members[v][ch.conn_pub] & members[u][ch.conn_sub])
            assert deltas.linked[u, v] == between.any()
            if deltas.overlap[u, v] or deltas.linked[u, v]:
                continue
            for k, j in ((ch.master, ch.num_scales - 1), (ch.num_scales - 1, 0)):
                after = moved(moved(assign, members, u, k), members, v, j)
                assert required_bandwidth(ch, after) - required_bandwidth(ch, assign) == \
                    pytest.approx(table.bandwidth[u, k] + table.bandwidth[v, j], abs=1e-9)
