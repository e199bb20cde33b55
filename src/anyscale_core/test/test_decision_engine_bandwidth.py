"""The decision engine and the link's bandwidth: a move out only onto a link that has held the
streams plus a margin (bandwidth_hold_s, bandwidth_margin), a node out staying with the smaller
stay margin, a link not measured yet or just back letting nothing out, weak_link_mbps, and the
hold after a loss (hold_after_loss_s, and a node's own: node_hold_after_loss_s)."""
import math

import pytest

from anyscale_core.allocators import make_allocator
from anyscale_core.decision_engine import DecisionEngine
from anyscale_core.decision_types import DecisionParams, StopNode

from decision_reports import remote, reports


def test_a_move_out_waits_until_the_link_has_held_the_bandwidth_with_a_margin(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=5.0, bandwidth_margin=0.3))
    e.adopt_or_start(reports(0.0), 0.0)
    # AR moves 6.05 Mbit/s when remote: with a 30 % margin it needs 7.9 Mbit/s held for 5 s.
    for t in range(0, 5):
        assert e.tick(reports(float(t), bandwidth=20.0), float(t)).events == []
    assert remote(e) == []                                       # not watched 5 s yet
    e.tick(reports(5.0, bandwidth=20.0), 5.0)
    assert remote(e) == ["amcl"]                                  # 0.22 Mbit/s: held
    e.tick(reports(6.0, bandwidth=7.5), 6.0)                     # a dip below 7.9
    for t in range(7, 11):
        e.tick(reports(float(t), bandwidth=20.0), float(t))
    assert remote(e) == ["amcl"]                                  # the dip is within 5 s
    e.tick(reports(11.9, bandwidth=20.0), 11.9)
    assert remote(e) == ["amcl"]                                  # 7.5 was in force until 7 s
    e.tick(reports(12.0, bandwidth=20.0), 12.0)
    assert remote(e) == ["amcl", "ar_recognition"]


def test_a_link_that_came_back_has_shown_nothing_yet(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=3.0, hysteresis_s=0.0))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(1, 7):
        e.tick(reports(float(t)), float(t))
    assert remote(e) == ["amcl", "ar_recognition"]
    e.tick({"robot": reports(7.0)["robot"]}, 7.0)                 # the laptop goes silent
    assert remote(e) == []
    for t in (8.0, 9.0, 10.0, 10.9):                              # back at 8 s
        assert e.tick(reports(t), t).events == []                 # not held 3 s yet
    assert [ev.node for ev in e.tick(reports(11.0), 11.0).events] == ["amcl"]


def test_a_node_out_stays_while_the_link_carries_it_with_the_smaller_stay_margin(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=2.0, bandwidth_margin=0.3,
                                      bandwidth_stay_margin=0.15))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(1, 6):
        e.tick(reports(float(t)), float(t))
    assert remote(e) == ["amcl", "ar_recognition"]
    # AR's 6.05 + AMCL's 0.22 Mbit/s: 7.5 keeps them with 15 % to spare (no flapping below the
    # 30 % a move out needs); 6.5 carries them, but the probe overrates what a stream gets.
    for t in range(6, 12):
        assert e.tick(reports(float(t), bandwidth=7.5), float(t)).events == []
    result = e.tick(reports(12.0, bandwidth=6.5), 12.0)
    assert [(ev.node, ev.reason) for ev in result.events] == [
        ("ar_recognition", "bandwidth 6.5 Mbit/s < 6.27 Mbit/s of streams + 15 %")]
    assert remote(e) == ["amcl"]


@pytest.mark.parametrize("allocator", ["paper", "paper_local", "optimal"])
def test_every_allocator_respects_the_hold(testbed_ch, allocator):
    e = DecisionEngine(testbed_ch, make_allocator(allocator),
                       DecisionParams(bandwidth_hold_s=2.0, bandwidth_margin=0.3))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(1, 6):
        e.tick(reports(float(t), bandwidth=7.0), float(t))   # carries AR, not with 30 % more
    assert remote(e) == ["amcl"]


def test_a_link_not_measured_yet_lets_nothing_out(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"), DecisionParams(bandwidth_hold_s=2.0))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(0, 6):                     # up, but no bulk probe answered yet: NaN
        e.tick(reports(float(t), bandwidth=math.nan), float(t))
    assert remote(e) == []
    for t in range(6, 10):
        e.tick(reports(float(t), bandwidth=20.0), float(t))
    assert remote(e) == ["amcl", "ar_recognition"]


def test_a_weak_link_brings_every_node_home_planned_and_lets_none_out(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=2.0, hysteresis_s=0.0, weak_link_mbps=5.5))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(1, 6):
        e.tick(reports(float(t)), float(t))
    assert remote(e) == ["amcl", "ar_recognition"]
    # AR's camera fills the link: the echo reads what it leaves. The link is not weak for
    # that, but cannot keep AR: the bandwidth rule brings AR home, AMCL stays.
    result = e.tick(reports(6.0, bandwidth=1.1), 6.0)
    assert [(ev.node, ev.reason) for ev in result.events] == [
        ("ar_recognition", "bandwidth 1.1 Mbit/s < 6.27 Mbit/s of streams + 15 %")]
    # AR's old instance streams until the new one has published, and the echo needs a reading
    # without it: for 3 s the low reading is still put down to AR's stream.
    assert e.tick(reports(7.0, bandwidth=4.5), 7.0).events == []
    # Then the link reads 4.5 Mbit/s by itself: weak. AMCL comes home, planned: its new
    # instance starts first, the old one stops once that one has published.
    result = e.tick(reports(9.5, bandwidth=4.5), 9.5)
    assert [(ev.node, ev.reason) for ev in result.events] == [
        ("amcl", "bandwidth 4.5 Mbit/s, below weak_link_mbps 5.5: home before the link is lost")]
    assert StopNode("amcl", "laptop", after_output_on="robot") in result.actions
    for t in range(10, 14):
        assert e.tick(reports(float(t), bandwidth=5.2), float(t)).events == []
    for t in range(14, 18):                           # 5.5 Mbit/s and more, held for 2 s
        e.tick(reports(float(t), bandwidth=12.0), float(t))
    assert remote(e) == ["amcl", "ar_recognition"]


@pytest.mark.parametrize("weak_link_mbps, bandwidth", [(5.5, 6.0), (0.0, 1.0)])
def test_a_thin_link_that_is_not_weak_keeps_amcl_out(testbed_ch, weak_link_mbps, bandwidth):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=0.0, hysteresis_s=0.0,
                                      weak_link_mbps=weak_link_mbps))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(1, 4):
        e.tick(reports(float(t), bandwidth=bandwidth), float(t))
    assert remote(e) == ["amcl"]


def test_after_a_loss_nothing_moves_out_until_the_link_has_been_up_for_hold_after_loss(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=2.0, hysteresis_s=0.0,
                                      hold_after_loss_s=6.0))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(1, 5):
        e.tick(reports(float(t)), float(t))
    assert remote(e) == ["amcl", "ar_recognition"]                 # no loss yet: 2 s were enough
    e.tick({"robot": reports(5.0)["robot"]}, 5.0)                 # the laptop goes silent
    assert remote(e) == []
    for t in (6.0, 8.0, 10.0, 10.9):                              # back at 6 s
        assert e.tick(reports(t), t).events == []                 # not up for 6 s yet
    assert [ev.node for ev in e.tick(reports(11.0), 11.0).events] == ["amcl"]


def test_a_node_with_its_own_shorter_hold_moves_out_while_the_others_wait(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=2.0, hysteresis_s=0.0,
                                      hold_after_loss_s=20.0,
                                      node_hold_after_loss_s={"amcl": 0.0}))
    e.adopt_or_start(reports(0.0), 0.0)
    for t in range(1, 5):
        e.tick(reports(float(t)), float(t))
    assert remote(e) == ["amcl", "ar_recognition"]
    e.tick({"robot": reports(5.0)["robot"]}, 5.0)                 # the laptop goes silent
    assert remote(e) == []
    for t in (6.0, 7.0):                                          # back at 6 s
        assert e.tick(reports(t), t).events == []                 # the bandwidth hold, 2 s
    for t in range(8, 25):
        e.tick(reports(float(t)), float(t))
        assert remote(e) == ["amcl"], t           # AR waits 20 s from the loss last seen, 5 s
    assert e.hold_after_loss_left(24.5) == {"ar_recognition": 0.5}
    e.tick(reports(25.0), 25.0)
    assert remote(e) == ["amcl", "ar_recognition"]


def test_a_weak_link_is_not_a_loss_for_hold_after_loss(testbed_ch):
    e = DecisionEngine(testbed_ch, make_allocator("paper"),
                       DecisionParams(bandwidth_hold_s=2.0, hysteresis_s=0.0,
                                      weak_link_mbps=5.5, hold_after_loss_s=60.0))
    e.adopt_or_start(reports(0.0, bandwidth=4.0), 0.0)
    for t in range(1, 4):
        e.tick(reports(float(t), bandwidth=4.0), float(t))       # weak: nothing goes out
    assert remote(e) == []
    for t in range(4, 7):
        e.tick(reports(float(t)), float(t))
    assert remote(e) == ["amcl"]                                  # out after the 2 s hold only
