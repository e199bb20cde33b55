"""LinkCapacity without the engine: a weak link carries nothing, the streams of the mapping
before a move count for STREAMS_SETTLE_S, a node out stays with the smaller margin, and what a
move out may count on is what the link held (BandwidthHold)."""
import math

from anyscale_core.link_capacity import STREAMS_SETTLE_S, BandwidthHold, LinkCapacity


def capacity(hold_s=2.0, margin=0.3, stay_margin=0.15, weak=5.0):
    return LinkCapacity(BandwidthHold(hold_s, margin), stay_margin, weak)


def test_a_reading_filled_by_our_own_streams_is_not_a_weak_link():
    link = capacity()
    assert link.is_weak(4.0, 0.0, streams_mbps=0.0)
    assert not link.is_weak(4.0, 0.0, streams_mbps=6.0)     # 4 + 6 carried
    assert not link.is_weak(math.nan, 0.0, streams_mbps=0.0)  # nothing measured is not weak


def test_the_streams_before_a_move_count_until_they_have_settled():
    link = capacity()
    link.mapping_changed(10.0, streams_before_mbps=6.0)
    assert not link.is_weak(1.0, 10.0 + STREAMS_SETTLE_S, streams_mbps=0.0)
    assert link.is_weak(1.0, 10.1 + STREAMS_SETTLE_S, streams_mbps=0.0)


def test_usable_is_the_reading_less_the_stay_margin_and_nothing_when_weak():
    link = capacity()
    assert math.isclose(link.usable(11.5, 0.0, streams_mbps=0.0), 10.0)
    assert link.usable(4.0, 0.0, streams_mbps=0.0) == 0.0


def test_moves_out_count_on_what_the_link_held_and_nothing_weak_or_lost():
    link = capacity(hold_s=2.0, margin=0.3)
    for t, mbps in ((0.0, 13.0), (1.0, 26.0), (2.0, 26.0)):
        link.observe(t, mbps, remote_up=True, streams_mbps=0.0)
    assert math.isclose(link.admissible(2.0), 10.0)          # the least of 2 s, less 30 %
    link.observe(3.0, 4.0, remote_up=True, streams_mbps=0.0)   # weak: shown as 0
    assert link.admissible(3.0) == 0.0
    link = capacity(hold_s=1.0)
    link.observe(0.0, 26.0, remote_up=True, streams_mbps=0.0)
    link.observe(1.0, math.nan, remote_up=True, streams_mbps=0.0)   # not measured: 0
    assert link.admissible(1.0) == 0.0
    link.observe(2.0, 26.0, remote_up=False, streams_mbps=0.0)     # down: 0, whatever it read
    assert link.admissible(2.0) == 0.0
