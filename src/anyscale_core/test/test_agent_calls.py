"""Repeated agent calls that fail are logged once per change of state; a planned move's wait
for the new instance's output ends on its first message, on a new decision, or on time."""
import threading
import time

from anyscale_core.agent_client import CallFailures
from anyscale_core.handover_ros import ABANDONED, PUBLISHED, TIMED_OUT, wait_for_output


def test_a_failing_call_is_reported_when_it_starts_failing_and_when_it_works_again():
    calls = CallFailures()
    key = ("renew_leases", "laptop")
    assert [calls.failed(key) for _ in range(5)] == [True, False, False, False, False]
    assert calls.failed(("renew_leases", "server"))          # each call and scale on its own
    assert calls.succeeded(key) == 5
    assert calls.succeeded(key) == 0                          # working: nothing to say
    assert calls.failed(key)                                  # failing again: said again


class FakeWatch:
    def __init__(self):
        self.published = threading.Event()


def test_the_wait_ends_when_the_new_instance_publishes():
    watch = FakeWatch()
    threading.Timer(0.2, watch.published.set).start()
    began = time.monotonic()
    assert wait_for_output(watch, 5.0, lambda: True) == PUBLISHED
    assert time.monotonic() - began < 2.0


def test_the_wait_is_abandoned_when_the_node_is_moved_again():
    moved = threading.Event()
    threading.Timer(0.2, moved.set).start()
    assert wait_for_output(FakeWatch(), 5.0, lambda: not moved.is_set()) == ABANDONED


def test_the_wait_times_out_and_keeps_the_old_lease_alive_meanwhile():
    beats = []
    assert wait_for_output(FakeWatch(), 2.2, lambda: True,
                           lambda: beats.append(time.monotonic())) == TIMED_OUT
    assert len(beats) in (2, 3)                    # about once a second
