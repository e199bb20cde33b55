"""Counting a topic's messages so that another thread can wait for the next one: the decision
node stops a node that hands its state over right after its latest output."""
import threading
from typing import Dict, Hashable


class MessageArrivals:
    def __init__(self):
        self._cond = threading.Condition()
        self._counts: Dict[Hashable, int] = {}

    def arrived(self, key: Hashable):
        with self._cond:
            self._counts[key] = self._counts.get(key, 0) + 1
            self._cond.notify_all()

    def wait_for_next(self, key: Hashable, timeout_s: float) -> bool:
        """Blocks until a message of `key` arrives after this call, or timeout_s passes;
        True if one arrived."""
        with self._cond:
            seen = self._counts.get(key, 0)
            return self._cond.wait_for(lambda: self._counts.get(key, 0) > seen, timeout_s)
