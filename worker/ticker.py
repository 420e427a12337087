"""A daemon thread that calls a function every few seconds: heartbeats and the reaper."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

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
    """

    def __init__(
        self,
        tick: Callable[[], None],
        interval_s: float,
        *,
        name: str,
        immediately: bool = False,
    ) -> None:
        if not interval_s > 0:
            raise ValueError(f"a ticker needs an interval > 0 s, got {interval_s!r}")
        self.tick = tick
        self.interval_s = float(interval_s)
        self.immediately = immediately
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
        while not self._stopping.wait(self.interval_s):
            self._safe_tick()

    def _safe_tick(self) -> None:
        try:
            self.tick()
        except Exception:
            logger.exception(
                "%s: tick failed; trying again in %g s", self._thread.name, self.interval_s
            )
