"""Slow clients (slowloris) against the service as shipped, and a normal client meanwhile.

Runs ``python -m app.serve`` as a user does (SQLite, the filesystem broker, one worker,
the API key it generates, read from its banner) and, for each ``--connections`` count:

- opens that many connections that each send a partial request head
  (``GET /health HTTP/1.1``, ``Host``, then one more header byte every ``--trickle-s``);
- meanwhile a normal client asks ``GET /health`` on a new connection, one request after
  another, for ``--hold-s`` seconds: latency (p50, p99, max) and failures (refused,
  reset, no answer within 5 s);
- samples the API process's open file descriptors and resident memory every second
  (the peak, and at the phase's end, before this script closes its slow connections);
- counts the slow connections the server closed, and when (seconds from connect).

With ``--reconnect`` a slow client whose connection is closed opens another at once, as a
determined attacker does; ``--server-nofile`` lowers the API process's limit on open
files (1,024 is a common default). Then the same with ``--body-connections`` clients
that send a complete ``POST /scenarios`` head (with the key; ``Content-Length: 100000``)
and its body one byte every ``--trickle-s``. Every slow connection is closed by this
script at the end of its phase. About 2 minutes with the defaults.

    python bench/slow_clients.py [--connections 100,1000,5000] [--hold-s 25]
        [--body-connections 100] [--reconnect] [--server-nofile N] [--repo DIR]
        [--json out.json]

``--repo`` runs another checkout's ``app.serve`` (the code before a change, say), with
this script's measurements. The load generator runs on the same machine.
"""

from __future__ import annotations

import asyncio
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from _common import (
    base_parser,
    free_port,
    generated_key,
    int_list,
    positive_int,
    print_header,
    print_table,
    service_env,
    spawn_service,
    stop_service,
)
from _common import write_json as _write_json

ROOT = Path(__file__).resolve().parents[1]
HEAD = b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: "
#: A normal request gets this long to be answered before it counts as a failure (s).
NORMAL_TIMEOUT_S = 5.0
PAGE_KB = os.sysconf("SC_PAGE_SIZE") / 1024
#: Seconds of the normal client alone, first.
BASELINE_S = 10


def _open_fds(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def _rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/statm") as fh:
        return int(fh.read().split()[1]) * PAGE_KB / 1024


@dataclass
class Service:
    process: subprocess.Popen[bytes]
    port: int
    key: str
    log_path: Path


def _start(repo: Path, data_dir: Path, port: int, nofile: int | None) -> Service:
    log_path = data_dir.parent / "serve.log"
    # As shipped: log level info (each request and each closed slow client is a line).
    argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", str(data_dir)]

    def limit_fds() -> None:
        if nofile is not None:
            _soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
            resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, hard))

    process = spawn_service(
        argv, log_path=log_path, cwd=repo, env=service_env(repo), preexec_fn=limit_fds
    )
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"serve exited:\n{log_path.read_text(errors='replace')}")
        status, _ = asyncio.run(_get_health(port))
        if status == 200:
            break
        time.sleep(0.1)
    else:
        raise RuntimeError(f"serve did not come up:\n{log_path.read_text(errors='replace')}")
    # Warm: the first requests import and cache what later ones use.
    for _ in range(20):
        asyncio.run(_get_health(port))
    key = generated_key(log_path)
    if not key:
        raise RuntimeError("serve printed no generated API key")
    return Service(process, port, key, log_path)


async def _get_health(port: int) -> tuple[int | None, str]:
    """``GET /health`` on a new connection: (status, "") or (None, why it failed)."""
    try:
        reader, writer = await asyncio.wait_for(
            asyncio.open_connection("127.0.0.1", port), NORMAL_TIMEOUT_S
        )
    except TimeoutError:
        return None, "connect timed out"
    except OSError as exc:
        return None, type(exc).__name__
    try:
        writer.write(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
        answer = await asyncio.wait_for(reader.read(), NORMAL_TIMEOUT_S)
    except TimeoutError:
        return None, "no answer in 5 s"
    except OSError as exc:
        return None, type(exc).__name__
    finally:
        writer.close()
    parts = answer.split(b" ", 2)
    if len(parts) < 2 or not parts[1].isdigit():
        return None, "no status line"
    return int(parts[1]), ""


@dataclass
class Slow:
    """One slow client: how long each of its connections the server closed had lived (s),
    whether its last one was still open at the phase's end, and its failed connects."""

    lifetimes: list[float] = field(default_factory=list)
    open_at_end: bool = False
    connect_failures: int = 0


async def _slow_client(
    port: int,
    head: bytes,
    trickle_s: float,
    stop: asyncio.Event,
    gate: asyncio.Semaphore,
    reconnect: bool,
) -> Slow:
    slow = Slow()
    while not stop.is_set():
        try:
            async with gate:
                reader, writer = await asyncio.wait_for(
                    asyncio.open_connection("127.0.0.1", port), 30
                )
        except (OSError, TimeoutError):
            slow.connect_failures += 1
            if not reconnect:
                break
            await asyncio.sleep(0.1)
            continue
        connected_at = time.monotonic()
        closed = False
        try:
            writer.write(head)
            while not stop.is_set():
                try:
                    data = await asyncio.wait_for(reader.read(4096), trickle_s)
                except TimeoutError:
                    writer.write(b"a")
                    continue
                if not data:  # the server closed it (any answer it sent is read past)
                    closed = True
                    break
        except OSError:
            closed = True
        finally:
            writer.close()
        if closed:
            slow.lifetimes.append(time.monotonic() - connected_at)
        else:
            slow.open_at_end = True
        if not (closed and reconnect):
            break
    return slow


@dataclass
class Phase:
    kind: str
    connections: int
    reconnect: bool
    normal_latencies_ms: list[float] = field(default_factory=list)
    normal_failures: dict[str, int] = field(default_factory=dict)
    #: Seconds from the phase's start to the normal client's last failure.
    last_failure_s: float | None = None
    fds: list[int] = field(default_factory=list)
    rss_mb: list[float] = field(default_factory=list)
    slow: list[Slow] = field(default_factory=list)


async def _phase(
    service: Service, kind: str, count: int, hold_s: float, trickle_s: float, reconnect: bool
) -> Phase:
    phase = Phase(kind, count, reconnect)
    pid = service.process.pid
    phase.fds.append(_open_fds(pid))
    phase.rss_mb.append(_rss_mb(pid))
    stop = asyncio.Event()
    if kind == "head":
        head = HEAD
    else:
        body = b"Content-Type: application/json\r\nContent-Length: 100000\r\n"
        head = (
            b"POST /scenarios HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: "
            + service.key.encode()
            + b"\r\n"
            + body
            + b"\r\n{"
        )
    # Connections opened 200 at a time, as fast as the server accepts them.
    gate = asyncio.Semaphore(200)
    clients = [
        asyncio.ensure_future(_slow_client(service.port, head, trickle_s, stop, gate, reconnect))
        for _ in range(count)
    ]
    start = time.monotonic()
    next_sample = start + 1.0
    while time.monotonic() - start < hold_s:
        before = time.perf_counter()
        status, why = await _get_health(service.port)
        if status == 200:
            phase.normal_latencies_ms.append((time.perf_counter() - before) * 1000)
        else:
            reason = why or f"status {status}"
            phase.normal_failures[reason] = phase.normal_failures.get(reason, 0) + 1
            phase.last_failure_s = time.monotonic() - start
        if time.monotonic() >= next_sample:
            phase.fds.append(_open_fds(pid))
            phase.rss_mb.append(_rss_mb(pid))
            next_sample += 1.0
        await asyncio.sleep(0.05)
    phase.fds.append(_open_fds(pid))
    phase.rss_mb.append(_rss_mb(pid))
    stop.set()
    phase.slow = list(await asyncio.gather(*clients))
    await asyncio.sleep(1.0)  # the server sees the closes
    return phase


def _quantile(values: list[float], q: float) -> float | None:
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def _summary(phase: Phase) -> dict[str, Any]:
    lifetimes = [t for slow in phase.slow for t in slow.lifetimes]
    return {
        "kind": phase.kind,
        "connections": phase.connections,
        "reconnect": phase.reconnect,
        "connect_failures": sum(slow.connect_failures for slow in phase.slow),
        "closed_by_server": len(lifetimes),
        "open_at_end": sum(slow.open_at_end for slow in phase.slow),
        "closed_after_s_median": statistics.median(lifetimes) if lifetimes else None,
        "closed_after_s_max": max(lifetimes) if lifetimes else None,
        "normal_requests": len(phase.normal_latencies_ms),
        "normal_p50_ms": _quantile(phase.normal_latencies_ms, 0.5),
        "normal_p99_ms": _quantile(phase.normal_latencies_ms, 0.99),
        "normal_max_ms": max(phase.normal_latencies_ms, default=None),
        "normal_failures": phase.normal_failures,
        "normal_last_failure_s": phase.last_failure_s,
        "fds_before": phase.fds[0],
        "fds_peak": max(phase.fds),
        "fds_at_end": phase.fds[-1],
        "rss_mb_before": phase.rss_mb[0],
        "rss_mb_peak": max(phase.rss_mb),
    }


def _print(summaries: list[dict[str, Any]], hold_s: float) -> None:
    rows = []
    for s in summaries:
        failures = ", ".join(f"{n} {why}" for why, n in s["normal_failures"].items()) or "0"
        rows.append(
            [
                "slow head" if s["kind"] == "head" else "slow body",
                s["connections"],
                s["closed_by_server"],
                s["open_at_end"],
                s["closed_after_s_median"],
                s["closed_after_s_max"],
                s["normal_requests"],
                s["normal_p50_ms"],
                s["normal_p99_ms"],
                s["normal_max_ms"],
                failures,
                s["normal_last_failure_s"],
                s["fds_before"],
                s["fds_peak"],
                s["fds_at_end"],
                s["rss_mb_before"],
                s["rss_mb_peak"],
            ]
        )
    print_table(
        [
            "slow clients",
            "n",
            "closed by server",
            f"open after {hold_s:g} s",
            "closed after s (median)",
            "(max)",
            "GET /health",
            "p50 ms",
            "p99 ms",
            "max ms",
            "failed",
            "last failed at s",
            "fds before",
            "fds peak",
            "fds at end",
            "RSS MB before",
            "RSS MB peak",
        ],
        rows,
        title="A normal client's GET /health (new connection each) while slow clients hold "
        "connections; fds and RSS of the API process",
    )


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--connections", type=int_list, default=[100, 1000, 5000])
    parser.add_argument("--body-connections", type=int, default=100, help="0: none")
    parser.add_argument("--hold-s", type=positive_int, default=25, help="seconds per phase")
    parser.add_argument(
        "--trickle-s", type=float, default=5.0, help="a slow client's seconds between bytes"
    )
    parser.add_argument(
        "--reconnect",
        action="store_true",
        help="a slow client whose connection is closed opens another at once",
    )
    parser.add_argument("--port", type=int, default=None, help="default: a free port")
    parser.add_argument(
        "--server-nofile",
        type=positive_int,
        default=None,
        help="the API process's soft limit on open files (default: this shell's)",
    )
    parser.add_argument("--repo", default=str(ROOT), help="the checkout to serve")
    args = parser.parse_args()
    needed = max([*args.connections, args.body_connections]) + 100
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < needed:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(needed, hard), hard))
    print_header("inertia-id serve: slow clients and a normal one", args)
    summaries = []
    with tempfile.TemporaryDirectory(prefix="slow-clients-") as tmp:
        data_dir = Path(tmp) / "data"
        service = _start(
            Path(args.repo).resolve(), data_dir, args.port or free_port(), args.server_nofile
        )
        try:
            phases = [("head", 0)] + [("head", n) for n in args.connections]
            if args.body_connections:
                phases.append(("body", args.body_connections))
            for kind, count in phases:
                hold_s = args.hold_s if count else min(args.hold_s, BASELINE_S)
                phase = asyncio.run(
                    _phase(service, kind, count, hold_s, args.trickle_s, args.reconnect)
                )
                summaries.append(_summary(phase))
                print(summaries[-1], flush=True)
        finally:
            stop_service(service.process)
    print()
    _print(summaries, args.hold_s)
    _write_json(args.json, args, {"phases": summaries})


if __name__ == "__main__":
    main()
