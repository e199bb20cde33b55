"""The decision engine's moves by Algorithm 1 on the test bed: AMCL then AR out on a good link
(make before break, leases renewed), AR back on a weak one, out again only after the hysteresis
T, critical nodes never moving, and Eq. 2 growing with better mappings."""
import pytest

from anyscale_core.decision_types import RenewLeases, StartNode, StopNode

from decision_reports import remote, reports


def test_good_link_moves_amcl_then_ar_and_renews_their_leases(engine):
    first = engine.tick(reports(1.0), 1.0)
    assert [(e.kind, e.node, e.to_scale) for e in first.events] == [("migrate", "amcl", "laptop")]
    start, stop, renew = first.actions          # make before break: start first
    assert start == StartNode("amcl", "laptop", (), 3.0, 36.0, 120.0)   # model CPU, memory
    # AMCL is declared pause_at_home: its robot instance is paused, not stopped.
    assert stop == StopNode("amcl", "robot", after_output_on="laptop", pause=True)
    assert renew == RenewLeases("laptop", ("amcl",), 3.0)
    engine.tick(reports(2.0), 2.0)
    assert remote(engine) == ["amcl", "ar_recognition"]
    third = engine.tick(reports(3.0), 3.0)
    assert third.events == []
    assert third.actions == [RenewLeases("laptop", ("amcl", "ar_recognition"), 3.0)]


def test_weak_link_sends_ar_back_and_keeps_amcl(engine):
    for t in (1.0, 2.0):
        engine.tick(reports(t), t)
    result = engine.tick(reports(3.0, bandwidth=3.0), 3.0)
    assert [(e.kind, e.node) for e in result.events] == [("migrate_back", "ar_recognition")]
    assert remote(engine) == ["amcl"]


def test_restored_link_moves_out_again_only_after_t(engine):
    for t in (1.0, 2.0):
        engine.tick(reports(t), t)
    engine.tick(reports(3.0, laptop=False), 3.0)
    assert remote(engine) == []
    for t in (4.0, 8.0, 12.9):
        assert engine.tick(reports(t), t).events == []                # hysteresis T = 10 s
    assert [e.node for e in engine.tick(reports(13.1), 13.1).events] == ["amcl"]


def test_critical_nodes_never_move(engine, testbed_ch):
    for t in range(1, 30):
        engine.tick(reports(float(t), bandwidth=50.0 if t % 7 else 0.5,
                            laptop=(t % 11 != 0)), float(t))
        for i in range(testbed_ch.num_nodes):
            if testbed_ch.critical[i]:
                assert engine.mapping()[testbed_ch.node_names[i]] == "robot"


def test_objective_grows_with_better_mappings(engine, testbed_ch):
    for t in (1.0, 2.0):
        engine.tick(reports(t), t)
    assert engine.objective.total(12.0) == pytest.approx(125 * 1 + 201 * 1 + 210 * 10)
