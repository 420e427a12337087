"""The classifiers the API and its verdict process keep loaded
(:class:`ClassifierCache`): a module of its own, so that the verdict process, which
judges telemetry off the API's threads (:mod:`app.verdicts`), imports the cache without
the ``/identify`` routes and FastAPI with them."""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import TYPE_CHECKING

from .expiring import Expiring

if TYPE_CHECKING:
    from inertia_id.classifiers.registry import CandidateClassifier

__all__ = ["ClassifierCache", "StoredClassifier"]


@dataclass(frozen=True)
class StoredClassifier:
    """What identifies a stored classifier, as a verdict names it: its id, the checksum
    over its payload (``sha256``, the key of its loaded copy) and its kind and provenance
    (training job, scenario, when it was stored). Read from the database in one look-up,
    its document aside."""

    classifier_id: str
    sha256: str
    kind: str
    job_id: str | None
    scenario_id: str
    created_at: datetime


class ClassifierCache:
    """Least-recently-used classifiers by (id, checksum), thread-safe, one load per entry.

    A cold classifier is loaded by one thread while the others asking for it wait for
    that load (a 2 MB document parsed once, not once per concurrent request); other
    classifiers are served meanwhile.

    The checksum of a classifier id, with its kind and provenance
    (:class:`StoredClassifier`), is remembered for ``checksum_ttl_s``: most requests then
    reach the database not at all (the look-up was 2 of a request's 8 ms on SQLite).

    :param size: how many classifiers to keep; 0 disables caching.
    :param checksum_ttl_s: how long an id's checksum is taken as known.
    :param clock: monotonic seconds (tests pass their own).
    """

    def __init__(
        self,
        size: int,
        *,
        checksum_ttl_s: float = 30.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.size = size
        self.checksum_ttl_s = checksum_ttl_s
        self._items: OrderedDict[tuple[str, str], CandidateClassifier] = OrderedDict()
        # More ids than classifiers: an id costs a few bytes, a classifier megabytes.
        self._stored: Expiring[str, StoredClassifier] = Expiring(4 * size, clock=clock)
        self._lock = threading.Lock()
        self._loading: dict[tuple[str, str], threading.Lock] = {}
        self.loads = 0

    def stored_of(self, classifier_id: str) -> StoredClassifier | None:
        """The classifier's checksum, kind and provenance, while remembered."""
        return self._stored.get(classifier_id)

    def remember_stored(self, stored: StoredClassifier) -> None:
        self._stored.put(stored.classifier_id, stored, ttl_s=self.checksum_ttl_s)

    def get(
        self, key: tuple[str, str], load: Callable[[], CandidateClassifier]
    ) -> CandidateClassifier:
        with self._lock:
            model = self._items.get(key)
            if model is not None:
                self._items.move_to_end(key)
                return model
            gate = self._loading.setdefault(key, threading.Lock())
        with gate:
            with self._lock:
                model = self._items.get(key)
                if model is not None:
                    return model
            try:
                model = load()
                self.loads += 1
                with self._lock:
                    if self.size > 0:
                        self._items[key] = model
                        self._items.move_to_end(key)
                        while len(self._items) > self.size:
                            self._items.popitem(last=False)
            finally:
                with self._lock:
                    self._loading.pop(key, None)
        return model

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, key: object) -> bool:
        return key in self._items
