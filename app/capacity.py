"""The API's CPU work behind one gate: a bounded queue, and 503 past capacity.

Identify and the response simulation compute in the API process. Run on the shared
thread pool they would take every thread under load, and ``/health``, ``GET /jobs``
and the dashboard would wait behind them. The gate gives them their own few threads
(``INERTIA_ID_COMPUTE_THREADS``) and a queue of bounded length
(``INERTIA_ID_COMPUTE_QUEUE``) and wait (``INERTIA_ID_COMPUTE_WAIT_S``): a request that
finds the queue full, or waits too long for a thread, is answered 503 with Retry-After
at once, so a client past the service's capacity learns it instead of hanging.
"""

from __future__ import annotations

import math
from collections.abc import Awaitable, Callable
from typing import Any, TypeVar

import anyio
from anyio import to_thread
from fastapi import HTTPException, status

from inertia_id.wording import counted

__all__ = ["ComputeGate", "Overloaded"]

T = TypeVar("T")


class Overloaded(HTTPException):
    """503 with Retry-After: the service is past its capacity for CPU work."""

    def __init__(self, reason: str, retry_after_s: float) -> None:
        super().__init__(
            status.HTTP_503_SERVICE_UNAVAILABLE,
            detail=f"the service is past its capacity ({reason}); try again in "
            f"{math.ceil(retry_after_s)} s",
            headers={"Retry-After": str(max(1, math.ceil(retry_after_s)))},
        )


class ComputeGate:
    """At most ``threads`` computations at once, at most ``queue`` waiting for one.

    :param threads: computations running at once (threads of their own).
    :param queue: requests allowed to wait for a thread; one more is refused at once.
    :param wait_s: longest wait for a thread before the request is refused.
    """

    def __init__(self, *, threads: int, queue: int, wait_s: float) -> None:
        if threads < 1 or queue < 0 or not wait_s > 0:
            raise ValueError(
                f"compute gate needs threads >= 1, queue >= 0, wait > 0; got {threads}, "
                f"{queue}, {wait_s}"
            )
        self.threads = threads
        self.queue = queue
        self.wait_s = wait_s
        self._limiter: anyio.CapacityLimiter | None = None
        self._unbounded: anyio.CapacityLimiter | None = None
        self.waiting = 0
        self.refused = 0

    @property
    def limiter(self) -> anyio.CapacityLimiter:
        # Made on first use, inside the event loop that serves the requests.
        if self._limiter is None:
            self._limiter = anyio.CapacityLimiter(self.threads)
            # The thread call itself must not wait on another limiter (the shared pool's):
            # the gate's token, taken first, is what bounds the threads.
            self._unbounded = anyio.CapacityLimiter(math.inf)
        return self._limiter

    async def run(self, function: Callable[..., T], *args: Any) -> T:
        """``function(*args)`` on one of the gate's threads, or 503 past capacity."""
        await self._enter()
        try:
            return await to_thread.run_sync(function, *args, limiter=self._unbounded)
        finally:
            self.limiter.release()

    async def run_async(self, function: Callable[..., Awaitable[T]], *args: Any) -> T:
        """``await function(*args)`` holding one of the gate's tokens (work done in
        another process: the gate still bounds how much of it is in flight)."""
        await self._enter()
        try:
            return await function(*args)
        finally:
            self.limiter.release()

    async def _enter(self) -> None:
        limiter = self.limiter
        if self.waiting >= self.queue and limiter.available_tokens == 0:
            self.refused += 1
            waits = "waits" if self.waiting == 1 else "wait"
            raise Overloaded(f"{counted(self.waiting, 'request')} already {waits} for CPU", 1.0)
        self.waiting += 1
        try:
            with anyio.fail_after(self.wait_s):
                await limiter.acquire()
        except TimeoutError:
            self.refused += 1
            raise Overloaded(f"no CPU within {self.wait_s:g} s", self.wait_s) from None
        finally:
            self.waiting -= 1
