"""A failed move's back-off: held back until the scale's load drops or the cost estimate newly
fits, else for a time that doubles with each failure in a row up to a maximum, reset by a stay
that lasts; a return for another reason (the link) is no failure."""
import pytest

from anyscale_core.placement_backoff import PlacementBackoff, PlacementBackoffParams, describe

MOVE = ("amcl", "laptop")
PARAMS = PlacementBackoffParams(first_s=10.0, max_s=300.0, success_s=60.0, retry_room=10.0)


def fail(b, now, load=20.0, fitted=True):
    return b.failed(MOVE, now, load, fitted, "/scan 3.1 Hz on laptop < 5 Hz")


def test_a_move_that_never_failed_is_not_held():
    assert not PlacementBackoff(PARAMS).blocked(MOVE, 0.0, 50.0, True)


def test_held_for_the_first_back_off_then_free():
    b = PlacementBackoff(PARAMS)
    entry = fail(b, 100.0)
    assert entry.failures == 1 and entry.delay_s == 10.0
    assert b.blocked(MOVE, 109.9, 20.0, True) and b.retry_in(MOVE, 105.0) == 5.0
    assert not b.blocked(MOVE, 110.0, 20.0, True) and b.retry_in(MOVE, 110.0) == 0.0
    assert not b.blocked(("amcl", "server"), 105.0, 20.0, True)     # another scale: not held


def test_the_back_off_doubles_with_each_failure_in_a_row_up_to_its_maximum():
    b = PlacementBackoff(PARAMS)
    delays, t = [], 0.0
    for _ in range(8):
        b.moved(MOVE, t)
        entry = fail(b, t + 5.0)       # out for 5 s, back for rate or CPU
        delays.append(entry.delay_s)
        t = entry.until
    assert delays == [10, 20, 40, 80, 160, 300, 300, 300]


def test_a_load_dropped_by_retry_room_ends_it_early():
    b = PlacementBackoff(PARAMS)
    fail(b, 0.0, load=60.0)
    assert b.blocked(MOVE, 5.0, 51.0, True)          # 9 points lower: not enough
    assert not b.blocked(MOVE, 5.0, 50.0, True)      # 10 points lower


def test_an_estimate_that_newly_fits_ends_it_early_one_that_fitted_already_does_not():
    b = PlacementBackoff(PARAMS)
    fail(b, 0.0, fitted=False)                       # sent back for CPU: it did not fit
    assert b.blocked(MOVE, 5.0, 20.0, False)
    assert not b.blocked(MOVE, 5.0, 20.0, True)
    fail(b, 20.0, fitted=True)                       # it fitted and failed all the same
    assert b.blocked(MOVE, 25.0, 20.0, True)


def test_a_stay_of_success_s_resets_it():
    b = PlacementBackoff(PARAMS)
    fail(b, 0.0)
    b.moved(MOVE, 10.0)
    assert b.settle(69.9) == [] and b.get(MOVE) is not None
    assert b.settle(70.0) == [MOVE] and b.get(MOVE) is None
    assert b.settle(80.0) == []                      # said once
    assert fail(b, 90.0).delay_s == 10.0             # counted from the first again


def test_a_shorter_stay_does_not_reset_it():
    b = PlacementBackoff(PARAMS)
    fail(b, 0.0)
    b.moved(MOVE, 10.0)
    assert fail(b, 40.0).failures == 2


def test_a_return_for_the_link_is_no_failure_and_no_success():
    b = PlacementBackoff(PARAMS)
    fail(b, 0.0)
    b.moved(MOVE, 10.0)
    b.left(MOVE)                                     # the link went at t = 30
    assert b.get(MOVE).failures == 1                 # not a second failure
    assert b.settle(100.0) == []                     # nor a stay that lasted
    b.moved(MOVE, 100.0)
    assert fail(b, 110.0).failures == 2


def test_max_s_0_turns_it_off():
    b = PlacementBackoff(PlacementBackoffParams(max_s=0.0))
    assert fail(b, 0.0) is None and not b.blocked(MOVE, 1.0, 50.0, False)


def test_the_log_line_says_why_and_when():
    b = PlacementBackoff(PARAMS)
    fail(b, 0.0)
    line = describe("amcl", "laptop", fail(b, 30.0, load=12.0, fitted=False), 10.0)
    assert line == ("amcl -> laptop backed off after its 2nd return in a row for rate or CPU "
                    "(/scan 3.1 Hz on laptop < 5 Hz): not tried again for 20 s, unless the load "
                    "of laptop drops 10 points below 12 %, or once its cost estimate fits there")
    refused = describe("amcl", "laptop", fail(b, 80.0, load=72.0), 10.0, refused=True)
    assert refused.startswith("amcl -> laptop backed off after its start refused for capacity "
                              "(3rd in a row)")
    assert describe("ekf", "laptop", b.get(MOVE), 10.0, refused=False).startswith(
        "ekf -> laptop backed off after a start refused for capacity")


@pytest.mark.parametrize("n,word", [(1, "1st"), (2, "2nd"), (3, "3rd"), (4, "4th"),
                                    (11, "11th"), (12, "12th"), (21, "21st")])
def test_ordinals(n, word):
    from anyscale_core.placement_backoff import ordinal
    assert ordinal(n) == word
