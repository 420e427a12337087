"""A condition that comes and goes (the database unreachable, a lock that cannot be
read or taken), logged once per *episode*: when it starts, when a new reason for it
appears, as a reminder every so often while it lasts, and once when it clears.

The worker's monitor meets such conditions at every beat (every 5 s): logged at each,
a database outage wrote a traceback of over 100 lines every 5 s for as long as it
lasted; logged once a process, a second outage later in the worker's life was never
logged at all. The standard library's logging has no such rate limit (its filters see
one record at a time, not whether the condition cleared), hence this small class.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

__all__ = ["REMIND_EVERY_S", "Episode"]

#: Seconds between two reminders that a condition still holds.
REMIND_EVERY_S = 300.0


class Episode:
    """One condition's episodes, logged on ``log``.

    :param log: the logger the lines go to.
    :param remind_every_s: seconds between two reminders while the condition lasts.
    :param clock: monotonic seconds (a test passes its own).
    """

    def __init__(
        self,
        log: logging.Logger,
        *,
        remind_every_s: float = REMIND_EVERY_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.log = log
        self.remind_every_s = remind_every_s
        self._clock = clock
        self._since: float | None = None
        self._reminded_at = 0.0
        self._reasons: set[str] = set()

    @property
    def active(self) -> bool:
        """Whether an episode is under way (the condition was seen, and not cleared)."""
        return self._since is not None

    def seen(self, reason: str, message: str, *, exc_info: bool = False) -> bool:
        """The condition holds, for ``reason``: ``message`` (its ``%s`` filled with the
        reason) logged as a warning if this starts an episode or the reason is new in
        it (with the traceback being handled when ``exc_info``), a reminder if the last
        line is ``remind_every_s`` old; nothing otherwise. Whether a line was logged."""
        now = self._clock()
        if self._since is None or reason not in self._reasons:
            if self._since is None:
                self._since = now
            self._reasons.add(reason)
            self._reminded_at = now
            self.log.warning(message, reason, exc_info=exc_info)
            return True
        if now - self._reminded_at >= self.remind_every_s:
            self._reminded_at = now
            self.log.warning(
                "still, for %.0f s: " + message, now - self._since, reason, exc_info=False
            )
            return True
        return False

    def cleared(self, message: str) -> bool:
        """The condition no longer holds: ``message`` (its ``%.0f`` filled with the
        episode's length in seconds) logged as info if an episode was under way, which
        ends; the next :meth:`seen` starts a new one. Whether a line was logged."""
        if self._since is None:
            return False
        lasted = self._clock() - self._since
        self._since, self._reasons = None, set()
        self.log.info(message, lasted)
        return True
