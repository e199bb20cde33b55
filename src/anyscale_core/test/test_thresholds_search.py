"""`anyscale thresholds`' pure part (no roscore): the ladders throttle can deliver, the verdict
per step, freq_min / freq_opt / tolerance, the probe's expressions and the subscriber's
remaps."""
import pytest

from anyscale_core.model import ModelError
from anyscale_core.thresholds_search import (ProbeBroken, StepResult, check_message,
                                             compile_condition, describe_step, find_rates,
                                             find_tolerance, next_step, outage_ladder,
                                             predict_seconds, rate_and_longest_silence,
                                             rate_ladder, subscriber_remaps, summarise_checks,
                                             throttle_argument, thresholds)


def test_rate_ladder_is_what_throttle_delivers_from_a_periodic_source():
    assert rate_ladder(10.0) == [10.0, 5.0, 3.33, 2.5, 2.0, 1.67, 1.25, 1.0]
    # 8 Hz from 10 Hz is 5 Hz with throttle: the nearest source / k is named.
    assert rate_ladder(10.0, [8, 6, 2]) == [10.0, 5.0, 2.0]
    assert rate_ladder(40.0, [30, 10]) == [40.0, 10.0]
    with pytest.raises(ModelError):
        rate_ladder(0.0)


@pytest.mark.parametrize("source,k", [(10.0, 2), (10.0, 3), (40.0, 4), (9.7, 10)])
def test_throttle_argument_passes_every_kth_message(source, k):
    """Simulates throttle's rule (pass a message when at least 1/rate passed since the last
    one passed) on a source with +-10 % jitter: exactly every k-th passes."""
    arg = throttle_argument(source, source / k)
    period, last, passed = 1.0 / source, None, []
    for i in range(200):
        t = i * period + (0.1 * period if i % 2 else -0.1 * period)
        if last is None or t - last >= 1.0 / arg:
            passed.append(i)
            last = t
    assert all(b - a == k for a, b in zip(passed, passed[1:]))
    assert throttle_argument(10.0, 10.0) >= 100      # k = 1: everything passes


def step(rate, passed, checks=10, value=None, outage=0.0):
    return StepResult(rate, outage, passed, checks, value, rate)


def test_next_step_goes_down_the_ladder_and_stops_at_the_first_failure():
    ladder = [10.0, 5.0, 2.0]
    assert next_step(ladder, [], 0.95) == 10.0
    assert next_step(ladder, [step(10, 10)], 0.95) == 5.0
    assert next_step(ladder, [step(10, 10), step(5, 9)], 0.95) is None
    assert next_step(ladder, [step(10, 10), step(5, 10), step(2, 10)], 0.95) is None


def test_a_step_without_checks_is_not_correct():
    assert not step(10, 0, checks=0).correct(0.5)
    assert step(10, 19, checks=20).correct(0.95) and not step(10, 18, checks=20).correct(0.95)


def test_freq_min_and_freq_opt_by_pass_share():
    results = [step(10, 10), step(5, 10), step(3.33, 10), step(2.5, 6)]
    assert find_rates(results, 0.5, 0.1) == (2.5, 3.33, True)
    assert find_rates(results, 0.95, 0.1) == (3.33, 3.33, False)


def test_freq_opt_by_value_is_where_the_error_stops_improving():
    # An error (lower is better) that keeps falling up to 5 Hz and then stays.
    results = [step(10, 10, value=0.050), step(5, 10, value=0.052), step(3.33, 10, value=0.09),
               step(2.5, 10, value=0.2), step(2, 3, value=0.9)]
    freq_min, freq_opt, every = find_rates(results, 0.95, 0.1)
    assert (freq_min, freq_opt, every) == (2.5, 5, False)
    assert find_rates(results, 0.95, 1.0)[1] == 3.33


def test_never_correct_gives_nothing():
    assert find_rates([step(10, 0)], 0.95, 0.1) == (None, None, False)


def test_tolerance_is_the_longest_correct_interruption():
    outs = [step(5, 10, outage=0.5), step(5, 10, outage=1), step(5, 10, outage=2),
            step(5, 2, outage=3)]
    assert find_tolerance(outs, 0.95) == (2, False)
    assert find_tolerance(outs[:3], 0.95) == (2, True)
    assert find_tolerance([step(5, 0, outage=0.5)], 0.95) == (0.0, False)
    th = thresholds([step(10, 10), step(5, 10)], outs, 0.95, 0.1)
    assert (th.freq_min, th.freq_opt, th.tolerance) == (5, 5, 2)
    assert th.freq_min_is_upper_bound and not th.tolerance_is_lower_bound
    # No interruption tried (the subscriber did not recover): no tolerance, and why.
    th = thresholds([step(10, 10), step(5, 2)], [], 0.95, 0.1, unmeasured="lost")
    assert th.tolerance is None and th.tolerance_unmeasured == "lost"
    assert thresholds([step(10, 10)], outs, 0.95, 0.1, unmeasured="x").tolerance_unmeasured == ""
    assert outage_ladder([2, 0.5, 2]) == [0.5, 2.0]
    with pytest.raises(ModelError):
        outage_ladder([0])


def test_probe_expressions():
    class Msg:
        data = 0.25
    condition = compile_condition("m.data < 0.3", "--condition")
    value = compile_condition("abs(m.data) * 2", "--value")
    assert check_message(condition, value, Msg(), "probe") == (True, 0.5)
    with pytest.raises(ModelError, match="--condition: not a Python expression over m"):
        compile_condition("m.data <", "--condition")
    broken = compile_condition("m.nope > 1", "--condition")
    with pytest.raises(ProbeBroken, match="probe: raised AttributeError"):
        check_message(broken, None, Msg(), "probe")


def test_subscriber_remaps_feed_the_throttled_topic():
    assert subscriber_remaps((), "/scan", "/scan_thresholds") == ["/scan:=/scan_thresholds"]
    assert subscriber_remaps((("chatter", "/chatter"), ("out", "/o")), "/chatter", "/c_t") == \
        ["chatter:=/c_t", "out:=/o", "/chatter:=/c_t"]


def test_prediction_and_description():
    assert predict_seconds(3, [1, 2], settle_s=5, step_s=20, start_s=15) == \
        15 + 3 * 25 + (5 + 1 + 20) + (5 + 2 + 20)
    assert predict_seconds(3, [1, 2], settle_s=5, step_s=20, start_s=15, recover_s=60) == \
        15 + 3 * 25 + 60 + (5 + 1 + 20) + (5 + 2 + 20)
    text = describe_step(StepResult(5.0, 2.0, 9, 10, 0.1, 4.8), 0.95)
    assert text.startswith("2 s without messages (at 5 Hz): delivered 4.80 Hz; probe passed 9 "
                           "of 10, mean value 0.1: NOT correct")


def test_a_steps_checks_summarised():
    assert summarise_checks([(True, 1.0), (False, 3.0), (True, None)]) == (2, 3, 2.0)
    assert summarise_checks([(True, None)]) == (1, 1, None)
    assert summarise_checks([]) == (0, 0, None)


def test_rate_and_longest_silence_as_the_subscriber_saw_them():
    # 10 s open, a message a second but none from 4 to 7 s.
    rate, silence = rate_and_longest_silence(0.0, [1, 2, 3, 4, 7, 8, 9], 10.0)
    assert rate == pytest.approx(0.7) and silence == pytest.approx(3.0)
    assert rate_and_longest_silence(5.0, [], 7.5) == (0.0, 2.5)
