"""A time limit and the grace after it, on a monotonic clock.

Light on purpose (no NumPy): the worker's heartbeat reads the grace of any job.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

from .errors import InputError

__all__ = [
    "GRACE_ASKED_MAX_S",
    "GRACE_FRACTION",
    "GRACE_MAX_S",
    "GRACE_MIN_S",
    "TIME_LIMIT_MIN_S",
    "Deadline",
    "check_grace",
    "check_time_limit",
    "time_limit_grace_s",
]

#: Once a time limit is spent, the re-score after the search (fresh draws of the best,
#: the front's members, the baselines) goes on only while a grace lasts: this fraction
#: of the limit, at least :data:`GRACE_MIN_S` (a few seconds hold the front's first
#: member and its baselines on the fresh draw, whatever the limit) and at most
#: :data:`GRACE_MAX_S`.
GRACE_FRACTION = 0.1
GRACE_MIN_S = 10.0
#: The default grace's cap: a tenth of the 6 h job ceiling would be 36 min past a "time
#: limit", more than anyone who set one expects. A job that wants a longer re-score asks
#: for its grace (``time_limit_grace_s``).
GRACE_MAX_S = 300.0
#: The longest grace a search may ask for: an hour. Longer is no grace after a limit but a
#: second, uncounted limit (who wants a longer re-score asks for a longer ``time_limit_s``);
#: the worker's heartbeat backstop waits out limit + grace, so an unbounded grace would
#: unbound it too; and a value typed in the wrong unit (60000 meaning ms) is refused rather
#: than kept running for most of a day.
GRACE_ASKED_MAX_S = 3600.0


#: The shortest time limit a job (``time_limit_s`` over the API, the service's ceiling
#: ``INERTIA_ID_JOB_TIME_LIMIT_S``) or a command (``--time-limit``) accepts, s. Below it
#: a limit is no budget but a slip, most likely a value in the wrong unit (milliseconds):
#: a training or a sweep would end with nothing done, a search after its first sequence
#: (whose re-score's grace alone is at least 10 s). Where a caller passes its own clock
#: (:class:`Deadline`, the core's requests), any span > 0 stands.
TIME_LIMIT_MIN_S = 1.0


def check_time_limit(value: Any) -> float | None:
    """A search's time budget: None (none), or a finite number of seconds > 0 (a job's
    or a command's at least :data:`TIME_LIMIT_MIN_S`, checked where they are read)."""
    if value is None:
        return None
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not (math.isfinite(value) and value > 0)
    ):
        raise InputError(
            f"time_limit_s must be a finite number of seconds > 0 (or none), got {value!r}"
        )
    return float(value)


def check_grace(value: Any) -> float | None:
    """The grace a search asks for after its time limit: None (the default rule, see
    :func:`time_limit_grace_s`), or a finite number of seconds >= 0 (0: stop at the
    limit, re-scoring only what is always re-scored) and at most
    :data:`GRACE_ASKED_MAX_S`."""
    if value is None:
        return None
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not (math.isfinite(value) and 0 <= value <= GRACE_ASKED_MAX_S)
    ):
        raise InputError(
            f"time_limit_grace_s must be a finite number of seconds >= 0 and <= "
            f"{GRACE_ASKED_MAX_S:g} (or none: {GRACE_FRACTION:.0%} of the limit, at least "
            f"{GRACE_MIN_S:g} s, at most {GRACE_MAX_S:g} s), got {value!r}"
        )
    return float(value)


def time_limit_grace_s(time_limit_s: float | None, grace_s: float | None = None) -> float | None:
    """The grace after ``time_limit_s`` in which a search's re-score may go on:
    ``grace_s`` when one is asked for, else :data:`GRACE_FRACTION` of the limit, at
    least :data:`GRACE_MIN_S` and at most :data:`GRACE_MAX_S`; None without a limit."""
    limit = check_time_limit(time_limit_s)
    asked = check_grace(grace_s)
    if limit is None:
        return None
    if asked is not None:
        return asked
    return min(GRACE_MAX_S, max(GRACE_MIN_S, GRACE_FRACTION * limit))


class Deadline:
    """The end of a search's time budget, on a monotonic clock (a wall clock set back or
    forward must not stretch or cut a search), and of the grace after it
    (:func:`time_limit_grace_s`) in which the re-score may go on.

    :param time_limit_s: seconds from now; None: never expires.
    :param clock: monotonic seconds; a test passes its own, so it needs no sleeps.
    :param grace_s: the grace asked for (None: the default rule).
    """

    def __init__(
        self,
        time_limit_s: float | None,
        clock: Callable[[], float] = time.monotonic,
        grace_s: float | None = None,
    ) -> None:
        self.time_limit_s = check_time_limit(time_limit_s)
        self.grace_s = time_limit_grace_s(self.time_limit_s, grace_s)
        self.clock = clock
        self.started = clock()

    def expired(self) -> bool:
        """True once ``time_limit_s`` seconds have passed since the deadline was set."""
        return self.time_limit_s is not None and self.clock() - self.started >= self.time_limit_s

    def grace_spent(self) -> bool:
        """True once the limit and its grace have passed: no re-score starts after it."""
        if self.time_limit_s is None or self.grace_s is None:
            return False
        return self.clock() - self.started >= self.time_limit_s + self.grace_s
