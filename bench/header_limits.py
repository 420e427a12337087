"""Oversized request heads against the API as the image runs it: answer, time, memory.

Runs the API with the Dockerfile's command (``uvicorn app.main:create_app --factory
--http app.request_deadlines:<protocol class>``; SQLite in a temporary data directory,
the key it generates), once with each of uvicorn's HTTP implementations (httptools, as
shipped, and h11), and sends ``GET /health`` with an oversized head, all of it at once
(well inside the 10 s head deadline), on ``--parallel`` connections together:

- ``10,000 headers``: ``X-Hnnnnn: v`` ten thousand times (about 130 KB);
- ``64 KiB, small headers``: 4,096 headers of 16 bytes each;
- ``one 1 MB header``, and ``one 16 MB header`` (``--big-mb``): a single header's value;
- ``30 KB of one header, unfinished``: a head that stops inside a header field and
  waits (for the answer, or the head deadline's close): httptools once held such a
  head's first read uncounted (up to 256 KB; 30 KB comes in one read on the loopback),
  until the deadline.

Once the API process's memory holds still after start-up (the app warms up the science
core in a thread), for each: what the client got (the status line, or how the connection ended), the
seconds from the first byte sent to that, and the API process's resident memory (RSS,
sampled every 5 ms) before and at its peak; then whether ``GET /health`` still answers.

    python bench/header_limits.py [--parallel 10] [--big-mb 1,16] [--repo DIR]
        [--json out.json]

``--repo`` runs another checkout's API (the code before a change, say) with this
script's measurements. The load generator runs on the same machine.
"""

from __future__ import annotations

import os
import socket
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from _common import (
    base_parser,
    free_port,
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
PAGE_MB = os.sysconf("SC_PAGE_SIZE") / 1024 / 1024
PROTOCOLS = {"httptools": "HttpToolsWithDeadlines", "h11": "H11WithDeadlines"}
#: How long a client waits for the answer, or the close, before it counts as none (s).
ANSWER_TIMEOUT_S = 30.0


def _rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/statm") as fh:
        return int(fh.read().split()[1]) * PAGE_MB


def _request(headers: bytes) -> bytes:
    return b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n" + headers + b"\r\n"


def attacks(big_mb: list[int]) -> dict[str, bytes]:
    """Each oversized request, by name."""
    out = {
        "10,000 headers": _request(b"".join(b"X-H%05d: v\r\n" % i for i in range(10_000))),
        # 16 bytes each: "X-S0000: 012345" and CRLF.
        "64 KiB, small headers": _request(
            b"".join(b"X-S%04d: 012345\r\n" % i for i in range(4096))
        ),
    }
    for mb in big_mb:
        out[f"one {mb} MB header"] = _request(b"X-Big: " + b"a" * (mb * 1_000_000) + b"\r\n")
    out["30 KB of one header, unfinished"] = _request(b"X-Big: " + b"a" * 30_000)[:-2]
    return out


@dataclass
class Outcome:
    answer: str
    seconds: float


def _send(port: int, request: bytes) -> Outcome:
    """Send ``request`` at once; the status line the server answered (or how the
    connection ended) and the seconds it took."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=ANSWER_TIMEOUT_S)
    start = time.perf_counter()
    received = b""
    ended = ""
    try:
        try:
            sock.sendall(request)
        except (BrokenPipeError, ConnectionResetError):
            ended = " (cut while sending)"
        while True:
            try:
                data = sock.recv(65536)
            except ConnectionResetError:
                ended = ended or " (reset)"
                break
            except TimeoutError:
                return Outcome(f"no answer in {ANSWER_TIMEOUT_S:g} s", ANSWER_TIMEOUT_S)
            if not data:
                break
            received += data
    finally:
        sock.close()
    status = received.split(b"\r\n", 1)[0].decode(errors="replace")
    return Outcome((status or "closed, no answer") + ended, time.perf_counter() - start)


class _Sampler(threading.Thread):
    """The peak RSS of ``pid`` while it runs (every 5 ms)."""

    def __init__(self, pid: int) -> None:
        super().__init__(daemon=True)
        self.pid = pid
        self.peak = _rss_mb(pid)
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.wait(0.005):
            self.peak = max(self.peak, _rss_mb(self.pid))


def _health(port: int) -> str:
    outcome = _send(port, _request(b""))
    return outcome.answer


def _measure(pid: int, port: int, request: bytes, parallel: int) -> dict[str, Any]:
    before = _rss_mb(pid)
    sampler = _Sampler(pid)
    sampler.start()
    outcomes: list[Outcome] = []
    threads = [
        threading.Thread(target=lambda: outcomes.append(_send(port, request)))
        for _ in range(parallel)
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    time.sleep(0.2)
    sampler.done.set()
    sampler.join()
    answers: dict[str, int] = {}
    for outcome in outcomes:
        answers[outcome.answer] = answers.get(outcome.answer, 0) + 1
    return {
        "request_bytes": len(request),
        "answers": answers,
        "seconds_max": max(o.seconds for o in outcomes),
        "rss_mb_before": before,
        "rss_mb_peak": sampler.peak,
        "rss_mb_after": _rss_mb(pid),
        "health_after": _health(port),
    }


def _settle(pid: int, timeout_s: float = 180.0) -> float:
    """Wait until the API process's RSS holds still (within 1 MB for 3 s): the app warms
    up the science core in a thread after it starts, and that adds 100 MB or more."""
    samples = [_rss_mb(pid)]
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(0.5)
        samples.append(_rss_mb(pid))
        recent = samples[-7:]
        if len(recent) == 7 and max(recent) - min(recent) < 1.0:
            break
    return samples[-1]


def _start(repo: Path, data_dir: Path, protocol: str, port: int) -> Any:
    """The Dockerfile's command, with ``protocol``'s class; once /health answers."""
    env = service_env(repo)
    env["INERTIA_ID_DATA_DIR"] = str(data_dir)
    argv = [sys.executable, "-m", "uvicorn", "app.main:create_app", "--factory"]
    argv += ["--http", f"app.request_deadlines:{PROTOCOLS[protocol]}"]
    argv += ["--host", "127.0.0.1", "--port", str(port)]
    log_path = data_dir.parent / f"uvicorn-{protocol}.log"
    data_dir.mkdir(parents=True, exist_ok=True)
    process = spawn_service(argv, log_path=log_path, cwd=repo, env=env)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"uvicorn exited:\n{log_path.read_text(errors='replace')}")
        try:
            if _health(port).startswith("HTTP/1.1 200"):
                return process
        except OSError:
            pass
        time.sleep(0.1)
    raise RuntimeError(f"uvicorn did not come up:\n{log_path.read_text(errors='replace')}")


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--parallel", type=positive_int, default=10, help="connections at once")
    parser.add_argument("--big-mb", type=int_list, default=[1, 16], help="single-header sizes")
    parser.add_argument("--protocols", default="httptools,h11", help="comma-separated")
    parser.add_argument("--repo", default=str(ROOT), help="the checkout to serve")
    args = parser.parse_args()
    protocols = [p.strip() for p in args.protocols.split(",") if p.strip()]
    unknown = sorted(set(protocols) - set(PROTOCOLS))
    if unknown:
        parser.error(f"--protocols: unknown {unknown}; known: httptools, h11")
    print_header("inertia-id API: oversized request heads", args)
    requests = attacks(args.big_mb)
    rows = []
    results = []
    with tempfile.TemporaryDirectory(prefix="header-limits-") as tmp:
        for protocol in protocols:
            port = free_port()
            process = _start(Path(args.repo).resolve(), Path(tmp) / protocol, protocol, port)
            try:
                _settle(process.pid)
                for name, request in requests.items():
                    figures = {"protocol": protocol, "attack": name}
                    figures |= _measure(process.pid, port, request, args.parallel)
                    results.append(figures)
                    print(figures, flush=True)
                    rows.append(
                        [
                            protocol,
                            name,
                            figures["request_bytes"],
                            ", ".join(f"{n} {a}" for a, n in figures["answers"].items()),
                            figures["seconds_max"],
                            figures["rss_mb_before"],
                            figures["rss_mb_peak"],
                            figures["rss_mb_peak"] - figures["rss_mb_before"],
                            figures["health_after"],
                        ]
                    )
            finally:
                stop_service(process)
    print()
    print_table(
        [
            "protocol",
            "request",
            "bytes",
            f"answers ({args.parallel} at once)",
            "s (max)",
            "RSS MB before",
            "RSS MB peak",
            "RSS MB growth",
            "GET /health after",
        ],
        rows,
        title="Oversized request heads, sent at once; RSS of the API process",
    )
    _write_json(args.json, args, {"results": results})


if __name__ == "__main__":
    main()
