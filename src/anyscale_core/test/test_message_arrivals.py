"""Waiting for the next message of a key, from another thread."""
import threading
import time

from anyscale_core.message_arrivals import MessageArrivals


def test_wait_ends_at_the_next_arrival_not_an_earlier_one():
    arrivals = MessageArrivals()
    arrivals.arrived("amcl")                 # before the wait: does not count
    timer = threading.Timer(0.1, arrivals.arrived, args=("amcl",))
    start = time.monotonic()
    timer.start()
    assert arrivals.wait_for_next("amcl", 5.0)
    assert 0.05 < time.monotonic() - start < 4.0


def test_wait_times_out_without_an_arrival_of_that_key():
    arrivals = MessageArrivals()
    timer = threading.Timer(0.05, arrivals.arrived, args=("ar_recognition",))
    timer.start()
    start = time.monotonic()
    assert not arrivals.wait_for_next("amcl", 0.3)
    assert time.monotonic() - start >= 0.29
    timer.join()
