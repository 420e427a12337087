"""What the request path's per-request wrappers cost in process: the ``StopCut``
middleware (``app/shutdown.py``, on every request) and the JSON ``Content-Type`` charset
check (``refuse_json_charset``, on every JSON body).

An end-to-end load (``bench/service_latency.py``) cannot resolve a few microseconds on a
shared 2-core machine (its runs vary 2-3x); this times the two pieces alone: a trivial
ASGI app called bare and under ``StopCut`` on one asyncio loop, and the charset check on
the two headers clients send. Prints medians of ``--repeats`` rounds of ``--calls``.

    python bench/request_path_overhead.py [--calls 100000] [--repeats 7]
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import time
from typing import Any

from app.api.routing import refuse_json_charset
from app.shutdown import StopCut

SCOPE: dict[str, Any] = {"type": "http", "method": "POST", "headers": []}


async def _inner(scope: Any, receive: Any, send: Any) -> None:
    await send({"type": "http.response.start", "status": 200, "headers": []})
    await send({"type": "http.response.body", "body": b"{}", "more_body": False})


async def _receive() -> dict[str, Any]:
    return {"type": "http.request", "body": b"", "more_body": False}


async def _send(message: Any) -> None:
    return None


async def _per_call_us(app: Any, calls: int) -> float:
    start = time.perf_counter()
    for _ in range(calls):
        await app(SCOPE, _receive, _send)
    return (time.perf_counter() - start) / calls * 1e6


async def _middleware(calls: int, repeats: int) -> tuple[float, float]:
    wrapped = StopCut(_inner)
    bare: list[float] = []
    cut: list[float] = []
    for _ in range(repeats):  # alternating, so that drift hits both alike
        bare.append(await _per_call_us(_inner, calls))
        cut.append(await _per_call_us(wrapped, calls))
    return statistics.median(bare), statistics.median(cut)


def _charset_us(header: str, calls: int, repeats: int) -> float:
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            refuse_json_charset(header)
        runs.append((time.perf_counter() - start) / calls * 1e6)
    return statistics.median(runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f}; median of {args.repeats} x {args.calls:,} calls")
    bare, cut = asyncio.run(_middleware(args.calls, args.repeats))
    print(f"ASGI call bare {bare:.2f} us, under StopCut {cut:.2f} us: adds {cut - bare:.2f} us")
    for header in ("application/json", "application/json; charset=utf-8"):
        per_call = _charset_us(header, args.calls, args.repeats)
        print(f"refuse_json_charset({header!r}): {per_call:.2f} us")


if __name__ == "__main__":
    main()
