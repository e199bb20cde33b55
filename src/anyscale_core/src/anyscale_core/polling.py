"""Waiting for a condition with a deadline (pure Python): this package's tests and the test
bed's tests and benches wait this way for processes, registrations and /proc entries."""
import time
from typing import Callable, TypeVar

T = TypeVar("T")


def wait_for(predicate: Callable[[], T], timeout_s: float = 10.0, period_s: float = 0.05) -> T:
    """The first truthy value of `predicate()` within timeout_s, polled every period_s; after
    the deadline, what the last call returned."""
    deadline = time.monotonic() + timeout_s
    while not (value := predicate()) and time.monotonic() < deadline:
        time.sleep(period_s)
    return value
