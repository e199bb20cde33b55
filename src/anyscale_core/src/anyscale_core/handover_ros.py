"""Make before break in rospy terms: seeing a node's new instance publish its output.

A planned move starts the node's instance on the target scale while the old one still runs
(the two register under different names, see SystemModel.instance_name), and the old one is
stopped once the new one has published. Which instance sent a message is in the connection
header rospy keeps with every message (`callerid`), so one subscriber per output topic tells
the two instances apart. The subscribers live only for the move, so a heavy output topic is not
pulled across the link for the rest of the run.
"""
import threading
import time
from typing import Callable, Sequence

import rospy

POLL_S = 0.05

PUBLISHED, ABANDONED, TIMED_OUT = "published", "abandoned", "timed out"


class OutputWatch:
    """Subscribes to `topics` (any type, not deserialised) and notes when `instance` (a fully
    qualified node name) has published `count` messages on them: its first one can come
    before it runs at its rate (a filter's first update, a map still being processed).
    Create it before the instance starts, so the subscription is in place when its first
    message goes out."""

    def __init__(self, topics: Sequence[str], instance: str, count: int = 1):
        self.instance = instance
        self.count = count
        self.received = 0
        self.published = threading.Event()
        self._subscribers = [rospy.Subscriber(t, rospy.AnyMsg, self._on_message, queue_size=1)
                             for t in topics]

    def _on_message(self, msg):
        header = getattr(msg, "_connection_header", None) or {}
        if header.get("callerid") == self.instance:
            self.received += 1
            if self.received >= self.count:
                self.published.set()

    def close(self):
        for sub in self._subscribers:
            sub.unregister()
        self._subscribers = []


def wait_for_output(watch: OutputWatch, timeout_s: float, still_wanted: Callable[[], bool],
                    every_second: Callable[[], None] = lambda: None) -> str:
    """PUBLISHED once the watched instance has published; ABANDONED as soon as `still_wanted()`
    is false (the node was moved again, or ROS shuts down); TIMED_OUT after timeout_s.
    `every_second` runs about once a second meanwhile (e.g. renewing the old instance's
    lease, which the decision loop no longer renews once the node is assigned elsewhere)."""
    deadline = time.monotonic() + timeout_s
    next_beat = time.monotonic()
    while True:
        if watch.published.wait(POLL_S):
            return PUBLISHED
        if not still_wanted() or rospy.is_shutdown():
            return ABANDONED
        now = time.monotonic()
        if now >= deadline:
            return TIMED_OUT
        if now >= next_beat:
            every_second()
            next_beat = now + 1.0
