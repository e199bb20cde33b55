"""PauseWatch on a scripted clock: a gap longer than its threshold is one pause, seen once."""
import threading

from anyscale_nav_demo.pause_watch import PauseWatch, ResumeStages


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_regular_checks_see_no_pause_and_a_long_gap_is_reported_once():
    clock = Clock()
    seen = []
    watch = PauseWatch(2.0, seen.append, clock)
    for _ in range(5):
        clock.t += 0.1
        assert watch.check() == 0.0
    clock.t += 30.0                          # paused for 30 s
    assert watch.check() == 30.0
    assert watch.check() == 0.0              # the other caller, right after: already reported
    clock.t += 1.9                           # a slow stretch below the threshold is no pause
    assert watch.check() == 0.0
    assert seen == [30.0]                    # reported once


def test_the_watch_thread_calls_back_for_a_pause_and_stops_when_asked():
    clock = Clock()
    seen, stop = [], threading.Event()
    watch = PauseWatch(2.0, seen.append, clock)
    clock.t += 5.0
    t = threading.Thread(target=watch.watch, args=(0.01, lambda: not stop.is_set()))
    t.start()
    for _ in range(200):
        if seen:
            break
        stop.wait(0.01)
    stop.set()
    t.join(2.0)
    assert seen == [5.0] and not t.is_alive()


def test_resume_stages_keep_each_stages_first_time_in_the_order_reached():
    stages = ResumeStages(100.0)
    stages.mark("fresh scan", 100.4)
    stages.mark("tf subscribed", 100.3)
    stages.mark("fresh scan", 100.5)        # a later scan: the stage was reached at 100.4
    stages.mark("first pose", 101.25)
    assert stages.summary() == "tf subscribed +0.30 s, fresh scan +0.40 s, first pose +1.25 s"
