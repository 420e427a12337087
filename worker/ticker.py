"""A daemon thread that calls a function every few seconds: heartbeats and the reaper."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from .episode import Episode

__all__ = ["Ticker"]

logger = logging.getLogger(__name__)


class Ticker:
    """Call ``tick`` every ``interval_s`` seconds on a daemon thread until :meth:`stop`.

    A failing tick is logged and the next one tried: a database that is briefly away
    must not stop a heartbeat for good.

    :param tick: the work of one beat.
    :param interval_s: seconds between the end of one tick and the start of the next.
    :param name: thread name, for logs and debuggers.
    :param immediately: also tick once as soon as the thread starts.
    :param sooner: asked every ``poll_s`` between ticks (cheap, no I/O); True ticks at
        once instead of waiting out the interval. A worker's monitor beats this way as
        soon as its task process is warm: the warm-up showed in /health up to a whole
        interval (5 s) after it ended, and every start that waits for a warm worker
        (a deployment's readiness check, ``inertia-id serve``'s own) waited with it.
    :param poll_s: seconds between two questions to ``sooner``.
    """

    def __init__(
        self,
        tick: Callable[[], None],
        interval_s: float,
        *,
        name: str,
        immediately: bool = False,
        sooner: Callable[[], bool] | None = None,
        poll_s: float = 0.2,
    ) -> None:
        if not interval_s > 0:
            raise ValueError(f"a ticker needs an interval > 0 s, got {interval_s!r}")
        if not poll_s > 0:
            raise ValueError(f"a ticker needs a poll > 0 s, got {poll_s!r}")
        self.tick = tick
        self.interval_s = float(interval_s)
        self.immediately = immediately
        self.sooner = sooner
        self.poll_s = float(poll_s)
        #: ``sooner`` failing: logged once an episode, not at every poll (5 a second).
        self._sooner_failing = Episode(logger)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> Ticker:
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 10.0) -> None:
        """Stop ticking; waits for a tick in progress (up to ``timeout_s``)."""
        self._stopping.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)

    def _run(self) -> None:
        if self.immediately:
            self._safe_tick()
        while not self._wait():
            self._safe_tick()

    def _wait(self) -> bool:
        """Wait for the next tick: the interval, or until ``sooner`` says so. True once
        the ticker is stopped."""
        if self.sooner is None:
            return self._stopping.wait(self.interval_s)
        due = time.monotonic() + self.interval_s
        while (left := due - time.monotonic()) > 0:
            if self._stopping.wait(min(self.poll_s, left)):
                return True
            if self._ask_sooner():
                return False
        return self._stopping.is_set()

    def _ask_sooner(self) -> bool:
        assert self.sooner is not None
        name = self._thread.name
        try:
            answer = bool(self.sooner())
        except Exception as exc:
            # A question that fails is no reason to tick early, nor to stop ticking.
            self._sooner_failing.seen(
                f"{type(exc).__name__}: {exc}",
                f"{name}: could not tell whether to tick early (%s); ticking every "
                f"{self.interval_s:g} s",
                exc_info=True,
            )
            return False
        self._sooner_failing.cleared(f"{name}: tells whether to tick early again after %.0f s")
        return answer

    def _safe_tick(self) -> None:
        try:
            self.tick()
        except Exception:
            logger.exception(
                "%s: tick failed; trying again in %g s", self._thread.name, self.interval_s
            )
