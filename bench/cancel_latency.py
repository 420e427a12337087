"""How long a search job takes to end after a cancel, and past a time limit.

Runs ``python -m app.serve`` (the embedded default: SQLite, filesystem broker, one
worker) and, for each ``--methods`` on the paper preset at ``--realisations`` and
``--length`` (the API's caps: 200 and 20):

- **cancel**: submits a search, waits until it has run ``--run-for`` s, POSTs
  ``/jobs/{id}/cancel`` and times the cancel POST to the job's terminal status (what
  the worker still did after it heard the cancel: re-scores, the front, baselines);
- **time limit** (with ``--time-limit``): submits the same search with
  ``time_limit_s`` and reports its run time (``run_time_s``), its status and
  ``result.stopped``: how far past the limit the job ends (the re-score in the limit's
  grace), and what that re-score reached (fresh draws, front candidates, baselines).

    python bench/cancel_latency.py [--methods nsga2,ppo] [--realisations 200]
        [--length 20] [--run-for 20] [--time-limit 30] [--port 18290]
"""

from __future__ import annotations

import argparse
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

ROOT = Path(__file__).resolve().parents[1]
TERMINAL = ("succeeded", "failed", "cancelled")
_KEY = re.compile(r"^API key:   (\S+)\n", re.MULTILINE)


def _start(data_dir: Path, port: int) -> tuple[subprocess.Popen[bytes], str, Path]:
    log_path = data_dir / "serve.log"
    argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", str(data_dir)]
    argv += ["--workers", "1", "--log-level", "warning"]
    with open(log_path, "wb") as log:
        process = subprocess.Popen(
            argv, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 300
    with httpx.Client(base_url=base, timeout=5) as client:
        while time.monotonic() < deadline:
            if process.poll() is not None:
                raise RuntimeError(f"serve exited:\n{log_path.read_text(errors='replace')}")
            try:
                health = client.get("/health")
                # Listed from its first beat, warming: up once warm.
                workers = health.json()["workers"] if health.status_code == 200 else {}
                if workers.get("count", 0) >= 1 and not workers.get("warming"):
                    break
            except httpx.TransportError:
                pass
            time.sleep(0.1)
        else:
            raise RuntimeError(f"serve did not come up:\n{log_path.read_text(errors='replace')}")
    found = _KEY.search(log_path.read_text(errors="replace"))
    if not found:
        raise RuntimeError("serve printed no generated API key")
    return process, found.group(1), log_path


def _wait(client: httpx.Client, job_id: str, until: Any, timeout_s: float = 3600) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = dict(client.get(f"/jobs/{job_id}").json())
        if until(job):
            return job
        time.sleep(0.05)
    raise RuntimeError(f"job {job_id} did not get there in {timeout_s} s")


def _submit(client: httpx.Client, scenario: str, params: dict[str, Any], seed: int) -> str:
    answer = client.post(
        "/jobs",
        json={"type": "search", "scenario_id": scenario, "seed": seed, "params": params},
    )
    if answer.status_code not in (200, 202):
        raise RuntimeError(f"POST /jobs answered {answer.status_code}: {answer.text}")
    return str(answer.json()["id"])


def _params(method: str, args: argparse.Namespace) -> dict[str, Any]:
    params: dict[str, Any] = {
        "method": method,
        "sequence_length": args.length,
        "n_realisations": args.realisations,
        "timesteps": 2_000_000,
        "patience_episodes": None,
    }
    if method == "ppo":
        params["ppo"] = {"n_steps": 64, "batch_size": 32}
    return params


def _rescored(result: dict[str, Any]) -> str:
    """What the re-score after the limit reached in its grace."""
    fresh, front = result.get("fresh") or {}, result.get("front") or {}
    baselines = result.get("baselines") or {}
    scored = sum("fresh_f1" in entry for entry in baselines.values())
    return (
        f"grace {(result.get('settings') or {}).get('time_limit_grace_s')} s: fresh draws "
        f"{len(fresh.get('f1') or [])}/{fresh.get('draws_asked')}, front candidates "
        f"re-scored {front.get('candidates_rescored')}, not {len(front.get('not_rescored') or [])}"
        f", baselines scored {scored}/{len(baselines)}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--methods", default="nsga2,ppo")
    parser.add_argument("--realisations", type=int, default=200)
    parser.add_argument("--length", type=int, default=20)
    parser.add_argument("--run-for", type=float, default=20.0, help="s before the cancel")
    parser.add_argument("--time-limit", type=float, default=None, help="s; none: no such run")
    parser.add_argument("--port", type=int, default=18290)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="cancel-latency-") as tmp:
        process, key, _log_path = _start(Path(tmp), args.port)
        try:
            with httpx.Client(
                base_url=f"http://127.0.0.1:{args.port}", headers={"X-API-Key": key}, timeout=30
            ) as client:
                scenario = client.post("/scenarios", json={"preset": "paper"}).json()["id"]
                for seed, method in enumerate(args.methods.split(",")):
                    params = _params(method, args)
                    job_id = _submit(client, scenario, params, seed)
                    _wait(client, job_id, lambda job: job["status"] == "running")
                    time.sleep(args.run_for)
                    asked = time.monotonic()
                    client.post(f"/jobs/{job_id}/cancel").raise_for_status()
                    job = _wait(client, job_id, lambda job: job["status"] in TERMINAL)
                    latency = time.monotonic() - asked
                    stopped = (job.get("result") or {}).get("stopped")
                    print(
                        f"{method:6s} L={args.length} realisations={args.realisations}: cancel "
                        f"after {args.run_for:g} s -> {job['status']} (stopped={stopped}) "
                        f"{latency:.1f} s after the cancel POST",
                        flush=True,
                    )
                    if args.time_limit is None:
                        continue
                    limited = _submit(
                        client, scenario, {**params, "time_limit_s": args.time_limit}, seed
                    )
                    job = _wait(client, limited, lambda job: job["status"] in TERMINAL)
                    result = job.get("result") or {}
                    print(
                        f"{method:6s} L={args.length} realisations={args.realisations}: "
                        f"time_limit_s {args.time_limit:g} -> {job['status']} "
                        f"(stopped={result.get('stopped')}) run {job['run_time_s']:.1f} s "
                        f"({job['run_time_s'] - args.time_limit:+.1f} s past the limit; "
                        f"{_rescored(result)})",
                        flush=True,
                    )
        finally:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(60)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(10)


if __name__ == "__main__":
    main()
