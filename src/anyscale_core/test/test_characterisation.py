"""Characterisation of the paper's test bed (golden values from Tables I and II) and of
random models: critical, pinned and migratable nodes, pruning counts."""
from dataclasses import replace

from hypothesis import given
import numpy as np

from anyscale_core.characterisation import (characterise, count_mappings, critical_node_names,
                                            enumerate_mappings, memory_fits)

from core_test_data import random_systems

# Table I: connection -> (freq_min, freq_opt, tolerance)
TABLE_I = {
    ("laser", "amcl"): (5, 10, 2), ("laser", "navigation"): (2, 10, 0),
    ("odometer", "odometry"): (10, 40, 0), ("camera", "ar_recognition"): (1, 30, 1),
    ("amcl", "ekf"): (2, 5, 2), ("odometry", "ekf"): (5, 10, 0),
    ("ekf", "navigation"): (2, 5, 0), ("ar_recognition", "navigation"): (1, 30, 1),
}


def test_testbed_connections_are_table_i(testbed):
    found = {(c.publisher, c.subscriber): (c.freq_min, c.freq_opt, c.tolerance)
             for c in testbed.connections}
    assert found == TABLE_I


def test_testbed_migratable_nodes_are_table_ii(testbed, testbed_ch):
    migratable = [n for n, m in zip(testbed_ch.node_names, testbed_ch.migratable) if m]
    assert migratable == ["amcl", "ar_recognition"]      # the paper: only AMCL and AR
    assert testbed.node("amcl").cpu_usage["robot"] == 50
    assert testbed.node("ar_recognition").cpu_usage["robot"] == 33
    amcl, ar = testbed_ch.node_index("amcl"), testbed_ch.node_index("ar_recognition")
    assert round(testbed_ch.bandwidth_of_node(amcl), 2) == 0.22   # 200 kbit/s of scans + poses
    assert round(testbed_ch.bandwidth_of_node(ar), 2) == 6.05     # 6 Mbit/s of images + results


def test_testbed_critical_nodes(testbed):
    assert set(critical_node_names(testbed)) == {"laser", "odometer", "odometry", "ekf",
                                                 "navigation"}


def test_testbed_mapping_counts(testbed_ch):
    count = count_mappings(testbed_ch)
    assert count.before_pruning == 2 ** 11
    assert count.after_pinning == 4
    assert count.after_memory == 4


def test_memory_prunes_combinations(testbed):
    small = characterise(replace(testbed, scales=tuple(
        s if s.master else replace(s, memory_mb=200) for s in testbed.scales)))
    # AMCL (150 MB) and AR (120 MB) each fit a 200 MB laptop, not both together.
    assert count_mappings(small).after_pinning == 4
    assert count_mappings(small).after_memory == 3


def test_initial_mapping_is_all_on_master(testbed_ch):
    assert (testbed_ch.initial_mapping() == testbed_ch.master).all()


@given(random_systems())
def test_critical_and_pinned_nodes_have_one_scale(ch):
    assert (ch.allowed.sum(axis=1) >= 1).all()
    assert (ch.allowed[ch.critical].sum(axis=1) == 1).all()
    assert ch.allowed[ch.critical, ch.master].all()
    assert (ch.allowed[ch.pinned].sum(axis=1) == 1).all()
    assert not (ch.migratable & ch.pinned).any()


@given(random_systems())
def test_counts_match_enumeration(ch):
    count = count_mappings(ch)
    assigns = enumerate_mappings(ch, ch.allowed)
    assert len(assigns) == count.after_pinning
    assert count.after_memory == int(memory_fits(ch, assigns).sum())
    assert count.after_memory <= count.after_pinning <= count.before_pruning
    assert np.isin(ch.initial_mapping(), np.arange(ch.num_scales)).all()
