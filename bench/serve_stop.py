"""How long ``inertia-id serve`` takes to stop on SIGTERM while clients post ``/identify``.

Runs ``python -m app.serve`` (the embedded default: SQLite, filesystem broker,
``--workers`` workers) from ``--repo`` (default this checkout; a checkout of the code
before to compare), stores a classifier trained here (the service's default kind, on the
paper preset), then starts ``--clients`` threads, each posting ``/identify`` on its own
keep-alive connection in a loop. After ``--load-for`` s, SIGTERM to serve; the figure is
the time from the signal to serve's exit. With ``--slow-uploads N``, N more connections
each send a ``POST /identify`` head and half its body, then nothing: requests in flight
that hold uvicorn for its whole grace (5 s), as a slow upload does. Serve's log is read
as it is written, each line stamped when it appears, to show when each shutdown step
happened (uvicorn's ``Shutting down`` and ``Finished server process``, serve's
``stopping workers`` or ``told N worker(s) to stop``, ``workers stopped`` and
``shutdown complete``, once the processes left are stopped)::

    python bench/serve_stop.py [--clients 10] [--slow-uploads 0] [--load-for 5]
        [--repeats 3] [--workers 1] [--repo PATH] [--json out.json]
"""

from __future__ import annotations

import json
import signal
import socket
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from _common import (
    GOOD_SEQUENCE,
    base_parser,
    begin,
    classifier_row,
    free_port,
    positive_int,
    print_table,
    service_env,
    spawn_service,
    wait_until_ok,
    write_json,
)

ROOT = Path(__file__).resolve().parents[1]
API_KEY = "bench-serve-stop-" + "k" * 24
#: Log lines that mark a shutdown step (substring -> step name).
STEPS = {
    "Shutting down": "uvicorn shutting down",
    "Finished server process": "uvicorn finished",
    "stopping workers": "workers told to stop",
    "worker(s) to stop": "workers told to stop",
    "workers stopped": "workers stopped",
    "no process of this service is left": "no process left",
}


def _classifier_row(database_url: str, scenario_id: str) -> str:
    """Train the default classifier here and store it as a train job would."""
    from sqlalchemy import create_engine
    from sqlalchemy.orm import Session

    from inertia_id import Scenario, train

    model = train(Scenario.paper(), GOOD_SEQUENCE, 20, np.random.default_rng(1))
    row = classifier_row(scenario_id, model)
    engine = create_engine(database_url)
    try:
        with Session(engine) as session:
            session.add(row)
            session.commit()
            return str(row.id)
    finally:
        engine.dispose()


def _identify_body(classifier_id: str) -> bytes:
    from inertia_id import Scenario, simulate

    flight = simulate(Scenario.paper(), GOOD_SEQUENCE, 1, np.random.default_rng(7))
    telemetry = {
        "time_s": flight.time_s.tolist(),
        "omega_rad_s": flight.omega_measured[3, 0].tolist(),
    }
    return json.dumps({"classifier_id": classifier_id, "telemetry": telemetry}).encode()


def _slow_upload(port: int, body: bytes) -> socket.socket:
    """A connection that sends a POST /identify head and half its body, then waits."""
    connection = socket.create_connection(("127.0.0.1", port), timeout=60)
    head = (
        f"POST /identify HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: {API_KEY}\r\n"
        f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n"
    )
    connection.sendall(head.encode() + body[: len(body) // 2])
    return connection


class _LogWatcher(threading.Thread):
    """Stamps each new line of ``path`` with the monotonic time it was first seen."""

    def __init__(self, path: Path) -> None:
        super().__init__(daemon=True)
        self.path = path
        self.lines: list[tuple[float, str]] = []
        self.done = threading.Event()

    def run(self) -> None:
        offset, partial = 0, b""
        while True:
            last = self.done.is_set()
            with open(self.path, "rb") as log:
                log.seek(offset)
                chunk = log.read()
            offset += len(chunk)
            *complete, partial = (partial + chunk).split(b"\n")
            now = time.monotonic()
            self.lines += [(now, line.decode(errors="replace")) for line in complete]
            if last:
                return
            time.sleep(0.01)

    def steps(self, since: float) -> dict[str, float]:
        found: dict[str, float] = {}
        for stamp, line in self.lines:
            for marker, step in STEPS.items():
                if marker in line and step not in found and stamp >= since:
                    found[step] = round(stamp - since, 2)
        return found


def one_run(args: Any, run: int) -> dict[str, Any]:
    repo = Path(args.repo).resolve()
    with tempfile.TemporaryDirectory(prefix="inertia-id-serve-stop-") as scratch:
        data_dir = Path(scratch) / "data"
        log_path = Path(scratch) / "serve.log"
        port = args.port or free_port()
        env = service_env(repo)
        env["INERTIA_ID_API_KEY"] = API_KEY
        argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir"]
        argv += [str(data_dir), "--workers", str(args.workers), "--log-level", "info"]
        process = spawn_service(argv, log_path=log_path, cwd=repo, env=env)
        watcher = _LogWatcher(log_path)
        watcher.start()
        base = f"http://127.0.0.1:{port}"
        headers = {"X-API-Key": API_KEY, "content-type": "application/json"}
        answered = [0] * args.clients
        stop_clients = threading.Event()
        slow: list[socket.socket] = []
        try:
            with httpx.Client(base_url=base, headers=headers, timeout=60) as client:
                wait_until_ok(client, process, log_path)
                scenario = client.post("/scenarios", json={"preset": "paper"}).json()["id"]
                classifier_id = _classifier_row(f"sqlite:///{data_dir / 'inertia-id.db'}", scenario)
                body = _identify_body(classifier_id)
                first = client.post("/identify", content=body)
                assert first.status_code == 200, first.text

            def post_loop(index: int) -> None:
                with httpx.Client(base_url=base, headers=headers, timeout=60) as own:
                    while not stop_clients.is_set():
                        try:
                            if own.post("/identify", content=body).status_code == 200:
                                answered[index] += 1
                        except httpx.HTTPError:
                            time.sleep(0.05)

            clients = [
                threading.Thread(target=post_loop, args=(i,), daemon=True)
                for i in range(args.clients)
            ]
            for thread in clients:
                thread.start()
            slow += [_slow_upload(port, body) for _ in range(args.slow_uploads)]
            time.sleep(args.load_for)
            signalled = time.monotonic()
            process.send_signal(signal.SIGTERM)
            code = process.wait(120)
            stop_s = time.monotonic() - signalled
        finally:
            stop_clients.set()
            for connection in slow:
                connection.close()
            if process.poll() is None:
                process.kill()
                process.wait(10)
            watcher.done.set()
            watcher.join(5)
        steps = watcher.steps(signalled)
        return {
            "run": run,
            "stop_s": round(stop_s, 2),
            "exit": code,
            "identify_answered": sum(answered),
            **steps,
        }


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--repo", default=str(ROOT), help="checkout whose serve is measured")
    parser.add_argument("--clients", type=positive_int, default=10)
    parser.add_argument(
        "--slow-uploads", type=int, default=0, help="requests left half sent through the stop"
    )
    parser.add_argument("--load-for", type=float, default=5.0, help="seconds of load first")
    parser.add_argument("--repeats", type=positive_int, default=3)
    parser.add_argument("--workers", type=positive_int, default=1)
    parser.add_argument("--port", type=int, default=0, help="default: a free port")
    args = begin(parser, "serve: SIGTERM to exit under /identify load")
    rows = [one_run(args, run) for run in range(1, args.repeats + 1)]
    columns = ["run", "stop_s", "exit", "identify_answered", *dict.fromkeys(STEPS.values())]
    print_table(columns, [[row.get(c, "-") for c in columns] for row in rows])
    stops = [row["stop_s"] for row in rows]
    print(f"\nstop time (s): median {statistics.median(stops):.2f}, max {max(stops):.2f}")
    write_json(args.json, args, {"runs": rows})


if __name__ == "__main__":
    main()
