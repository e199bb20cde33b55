"""DropStreak: a streak of dropped scans is told when it starts and summed up when it ends."""
from anyscale_nav_demo.drop_streak import DropStreak


def test_a_streak_is_announced_once_and_summed_up_when_an_input_is_used_again():
    s = DropStreak()
    assert s.used() is None                    # nothing dropped: nothing to say
    assert s.dropped(10.0) is True
    assert s.dropped(10.6) is False and s.dropped(11.2) is False
    count, length = s.used()
    assert count == 3 and abs(length - 1.2) < 1e-9
    assert s.used() is None                    # said once
    assert s.total == 3


def test_each_streak_is_counted_on_its_own_and_the_total_keeps_growing():
    s = DropStreak()
    s.dropped(1.0)
    count, length = s.used()
    assert (count, length) == (1, 0.0)
    assert s.dropped(5.0) is True
    s.dropped(5.5)
    count, length = s.used()
    assert count == 2 and abs(length - 0.5) < 1e-9
    assert s.total == 3
