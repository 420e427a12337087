"""Answers the API remembers for a while, so that most requests skip a database look-up:
API-key checks (:class:`app.security.KeyVerifier`) and classifier checksums
(:class:`app.classifier_cache.ClassifierCache`)."""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

__all__ = ["Expiring"]

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")


class Expiring(Generic[K, V]):
    """Values remembered until their own deadline, at most the ``size`` most recently
    stored (the oldest go first); thread-safe.

    :param size: how many values to keep; 0 keeps none.
    :param clock: monotonic seconds (tests pass their own).
    """

    def __init__(self, size: int, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.size = size
        self._clock = clock
        self._values: OrderedDict[K, tuple[V, float]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: K) -> V | None:
        """The value stored for ``key``; None when there is none or its time is up."""
        with self._lock:
            known = self._values.get(key)
        if known is None or known[1] <= self._clock():
            return None
        return known[0]

    def put(self, key: K, value: V, *, ttl_s: float) -> None:
        """Remember ``value`` for ``key`` for ``ttl_s`` seconds from now."""
        if self.size <= 0:
            return
        with self._lock:
            self._values[key] = (value, self._clock() + ttl_s)
            self._values.move_to_end(key)
            while len(self._values) > self.size:
                self._values.popitem(last=False)
