"""hold_replay on synthetic links: the node's time out and its moves under a hold policy."""
import pytest

from anyscale_testbed.hold_replay import ReplayRules, doubling_hold, fixed_hold, replay_hold


def link(*pieces, step=0.2):
    """(t, Mbit/s) samples every `step` s from pieces of (seconds, Mbit/s)."""
    samples, t = [], 0.0
    for seconds, mbps in pieces:
        for _ in range(round(seconds / step)):
            samples.append((round(t, 6), mbps))
            t += step
    return samples


def test_after_a_clean_loss_the_hold_delays_the_move_out_by_what_it_adds():
    trace = link((100, 10.0), (1, 0.0), (99, 10.0))
    none, twenty = replay_hold(trace, fixed_hold(0.0)), replay_hold(trace, fixed_hold(20.0))
    # out at 5 s (bandwidth hold); after the loss at 100-101 s: T from the return at 100 s
    # (110 s) without a hold of its own, 20 s from the loss last seen (100.8 s) with one
    assert none.moves_out == twenty.moves_out == 2 and none.ended_soon == 0
    assert none.out_s == pytest.approx(95.0 + 90.0, abs=0.3)
    assert twenty.out_s == pytest.approx(95.0 + 79.2, abs=0.3)
    assert none.carried_s == pytest.approx(199.0, abs=0.3)
    assert none.out_share == pytest.approx(185.0 / 199.0, abs=0.01)


def test_a_flickering_link_ends_moves_soon_without_a_hold_and_not_with_one():
    flicker = [(8, 10.0), (0.6, 0.0)] * 6
    trace = link((20, 10.0), (1, 0.0), *flicker, (60, 10.0))
    rules = ReplayRules(hysteresis_s=0.0)
    none = replay_hold(trace, fixed_hold(0.0), rules)
    twenty = replay_hold(trace, fixed_hold(20.0), rules)
    # the first 20 s and the last 60 s: one move each, not ended soon; each 8 s piece between:
    # out after 5 s, ended by the loss 3 s later
    assert none.moves_out == 8 and none.ended_soon == 6
    assert twenty.ended_soon == 0 and twenty.moves_out == 2
    assert twenty.out_s < none.out_s


def test_a_weak_link_brings_the_node_home_but_is_no_loss():
    trace = link((30, 10.0), (5, 4.5), (30, 10.0))
    r = replay_hold(trace, fixed_hold(60.0), ReplayRules(hysteresis_s=0.0))
    assert r.moves_out == 2 and r.ended_soon == 0            # out again after 5 s of good link
    assert r.carried_s == pytest.approx(60.0, abs=0.3)
    # a planned return soon after the move: not a link-loss return
    soon = replay_hold(link((8, 10.0), (1, 4.5), (10, 10.0)), fixed_hold(0.0))
    assert soon.moves_out == 2 and soon.ended_soon == 0       # out at 5 s, back at 8, out at 18
    assert replay_hold([], fixed_hold(0.0)).moves_out == 0


def test_the_doubling_hold_is_short_after_a_clean_loss_and_grows_with_repeated_ones():
    hold = doubling_hold(5.0, 60.0, 40.0)
    assert hold([10.0], 10.0) == 5.0
    assert hold([10.0, 30.0, 50.0], 50.0) == 20.0
    assert hold([10.0, 30.0, 50.0, 55.0, 58.0, 59.0], 59.0) == 40.0
    assert hold([10.0, 100.0], 100.0) == 5.0                 # the first is out of the window
