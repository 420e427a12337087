"""Helpers shared by the benchmark scripts in this folder.

The scripts are run as ``python bench/<name>.py``, which puts this folder on
``sys.path``, so they import this module as ``_common``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import re
import signal
import socket
import statistics
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")

# A cell that reads as a number (possibly with thousands separators, a trailing "x" or
# "%", or "-" for missing) is right-aligned.
_NUMERIC = re.compile(r"^(-|nan|[-+]?[\d,]*\.?\d+(e[-+]?\d+)?[x%]?)$")

# The paper's hand-designed sequence: the three positive-axis thrusters at full duty
# (level index 4 of 0..4) every step, the three negative-axis ones off.
GOOD_SEQUENCE: list[list[int]] = [[4, 4, 4, 0, 0, 0]] * 4


def base_parser(description: str) -> argparse.ArgumentParser:
    """An argument parser with the options every benchmark takes (--seed, --json)."""
    parser = argparse.ArgumentParser(
        description=description,
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of every random draw")
    parser.add_argument(
        "--json", metavar="PATH", default=None, help="also write the figures as JSON to PATH"
    )
    return parser


def add_realisations(parser: argparse.ArgumentParser, *, default: int = 20) -> None:
    """--realisations: the series simulated per candidate (one option, one meaning, in
    every benchmark that trains or scores)."""
    parser.add_argument(
        "--realisations", type=positive_int, default=default, help="realisations per candidate"
    )


def add_steps(parser: argparse.ArgumentParser) -> None:
    """--steps: the length L of the benchmark's seeded random sequence."""
    parser.add_argument(
        "--steps", type=positive_int, default=4, help="actuation steps L of the random sequence"
    )


def add_length(parser: argparse.ArgumentParser) -> None:
    """--length: the steps L of the sequences a search benchmark looks for."""
    parser.add_argument("--length", type=positive_int, default=4, help="sequence steps L")


def add_repo(parser: argparse.ArgumentParser) -> None:
    """--repo: the checkout whose service a benchmark starts (this one by default)."""
    parser.add_argument(
        "--repo", type=str, default=str(Path(__file__).resolve().parents[1]), help="checkout run"
    )


def int_list(text: str) -> list[int]:
    """argparse type: a comma-separated list of positive integers."""
    try:
        values = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected integers separated by commas, got {text!r}"
        ) from None
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive integers, got {text!r}")
    return values


def float_list(text: str) -> list[float]:
    """argparse type: a comma-separated list of positive numbers."""
    try:
        values = [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas, got {text!r}"
        ) from None
    if not values or any(v <= 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers, got {text!r}")
    return values


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value}")
    return value


def random_sequence(
    rng: np.random.Generator, n_steps: int, n_thrusters: int, n_levels: int
) -> np.ndarray:
    """(n_steps, n_thrusters) level indices drawn uniformly in 0..n_levels-1."""
    return rng.integers(0, n_levels, size=(n_steps, n_thrusters))


def sequence_text(sequence: Any) -> str:
    """A sequence on one line: steps separated by '/', e.g. '444000/444000'."""
    arr = np.asarray(sequence, dtype=int)
    sep = "" if arr.max(initial=0) < 10 else ","
    return "/".join(sep.join(str(v) for v in row) for row in arr)


def best_of(fn: Callable[[], T], repeats: int) -> tuple[float, list[float], T]:
    """Call ``fn`` ``repeats`` times; return (best seconds, all seconds, last result)."""
    times: list[float] = []
    result: Any = None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return min(times), times, result


def timed(fn: Callable[[], T]) -> tuple[float, T]:
    """Call ``fn`` once; return (seconds, result)."""
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def add_flight_bounds(parser: argparse.ArgumentParser) -> None:
    """The per-flight benches' options: lengths, residual bound, impulse, flights."""
    parser.add_argument("--lengths", type=int_list, default=[4, 8], help="sequence lengths")
    parser.add_argument("--bound", type=float, default=0.01, help="residual rate, rad/s")
    parser.add_argument("--max-impulse", type=float, default=24.0, help="N m s")
    parser.add_argument(
        "--flights", type=positive_int, default=4000, help="independent flights per candidate"
    )


def add_sweep_sizes(parser: argparse.ArgumentParser) -> None:
    """A sweep bench's sizes: test series per point and the ceiling's realisations."""
    from inertia_id.evaluation.ceiling import DEFAULT_CEILING_REALISATIONS

    parser.add_argument("--n-test", type=int, default=500, help="test series per point")
    parser.add_argument(
        "--ceiling-realisations",
        type=int,
        default=DEFAULT_CEILING_REALISATIONS,
        help="the ceiling's training per candidate",
    )


def constrained_front(
    scenario: Any, length: int, seed: int, constraints: dict[str, float]
) -> tuple[dict[str, Any], list[dict[str, Any]], float, str]:
    """An NSGA-II front under ``constraints``: (front, its members, seconds, the first
    member's confirmed accuracy at each design noise as text)."""
    from inertia_id.search import OperatorSettings, pareto_search

    seconds, result = timed(
        lambda: pareto_search(
            scenario,
            sequence_length=length,
            seed=seed,
            operator=OperatorSettings(constraints=constraints),
        )
    )
    front = result.front or {}
    confirmation = front.get("confirmation") or {}
    confirmed = " / ".join(f"{a:.4f}" for a in confirmation.get("accuracy_by_noise", []))
    return front, front.get("members", []), seconds, confirmed


def summary(values: Sequence[float]) -> dict[str, float]:
    """min / median / max / mean of some figures."""
    vals = [float(v) for v in values]
    return {
        "min": min(vals),
        "median": float(statistics.median(vals)),
        "max": max(vals),
        "mean": float(statistics.fmean(vals)),
    }


def format_table(
    headers: Sequence[str], rows: Sequence[Sequence[Any]], title: str | None = None
) -> str:
    """A plain-text table; numbers right-aligned, text left-aligned."""
    cells = [[_cell(v) for v in row] for row in rows]
    widths = [len(h) for h in headers]
    for row in cells:
        for i, text in enumerate(row):
            widths[i] = max(widths[i], len(text))
    numeric = [
        bool(cells) and all(_NUMERIC.match(row[i]) for row in cells if i < len(row))
        for i in range(len(headers))
    ]

    def line(values: Sequence[str]) -> str:
        parts = [
            v.rjust(widths[i]) if numeric[i] else v.ljust(widths[i]) for i, v in enumerate(values)
        ]
        return "  ".join(parts).rstrip()

    out = []
    if title:
        out.append(title)
    out.append(line(list(headers)))
    out.append("  ".join("-" * w for w in widths))
    out.extend(line(row) for row in cells)
    return "\n".join(out)


def state_runs(samples: Sequence[tuple[float, Sequence[Any]]]) -> list[list[Any]]:
    """Polled states as table rows ``[from s, to s, *state]``: a run of polls that saw the
    same state is one row (what /health said second by second, in the health benches)."""
    rows: list[list[Any]] = []
    for at, state in samples:
        if rows and tuple(rows[-1][2:]) == tuple(state):
            rows[-1][1] = f"{at:.1f}"
        else:
            rows.append([f"{at:.1f}", f"{at:.1f}", *state])
    return rows


def print_table(
    headers: Sequence[str], rows: Sequence[Sequence[Any]], title: str | None = None
) -> None:
    print(format_table(headers, rows, title))
    print(flush=True)


def _cell(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int | np.integer):
        return f"{int(value):,}"
    if isinstance(value, float | np.floating):
        value = float(value)
        if value != value:  # NaN
            return "nan"
        if value == 0.0:
            return "0"
        magnitude = abs(value)
        if magnitude >= 1e6 or magnitude < 1e-3:
            return f"{value:.3g}"
        if magnitude >= 100:
            return f"{value:,.1f}"
        return f"{value:.3f}"
    return str(value)


def environment() -> dict[str, Any]:
    """Versions and machine facts recorded with every run."""
    import numba
    import sklearn
    import tslearn

    import inertia_id

    return {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "scikit-learn": sklearn.__version__,
        "tslearn": tslearn.__version__,
        "inertia_id": inertia_id.__version__,
    }


def print_header(title: str, args: argparse.Namespace) -> None:
    env = environment()
    print(title)
    print("=" * len(title))
    print(
        f"python {env['python']}, numpy {env['numpy']}, tslearn {env['tslearn']}, "
        f"numba {env['numba']}; {env['cpu_count']} CPUs ({env['platform']})"
    )
    options = ", ".join(f"{k}={v}" for k, v in vars(args).items() if k != "json")
    print(f"options: {options}")
    print(flush=True)


def begin(parser: argparse.ArgumentParser, title: str) -> argparse.Namespace:
    """Parse the command line and print the run's header (``title``, the environment and
    the options), which is how every benchmark that needs no check in between begins."""
    args = parser.parse_args()
    print_header(title, args)
    return args


def write_json(path: str | None, args: argparse.Namespace, figures: dict[str, Any]) -> None:
    """Write ``figures`` with the options and environment to ``path`` (if given)."""
    if not path:
        return
    doc = {"options": vars(args), "environment": environment(), **figures}
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=2, default=_json_default)
        fh.write("\n")
    print(f"figures written to {path}")


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    raise TypeError(f"cannot write {type(value).__name__} as JSON")


def warm_up_numba() -> float:
    """JIT-compile tslearn's DTW and soft-DTW kernels on a tiny problem; return seconds.

    Fits both our classifier and tslearn's TimeSeriesKMeans with every metric on ten
    short random series, so that later timings do not include numba's compilation.
    """
    from inertia_id import METRICS, InertiaClassifier

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from tslearn.clustering import TimeSeriesKMeans

    rng = np.random.default_rng(12345)
    X = rng.standard_normal((10, 8, 3)) * 1e-3
    y = np.repeat(np.arange(2), 5)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for metric in METRICS:
            InertiaClassifier(
                metric, n_init=1, max_iter=2, max_iter_barycenter=2, random_state=0
            ).fit(X, y)
            TimeSeriesKMeans(
                n_clusters=2, metric=metric, max_iter=2, max_iter_barycenter=2, random_state=0
            ).fit(X)
    return time.perf_counter() - start


def torque_only(omega, torque, inertia, inertia_inv):
    """Euler's equations without the gyroscopic term ω × Iω: patched over
    ``inertia_id.physics.dynamics.euler_rates`` for the linear-response ablations."""
    return torque @ inertia_inv


@contextlib.contextmanager
def without_gyroscopic_term() -> Iterator[None]:
    """Simulate without ω × Iω (the linear response) inside the block.

    The simulator's compiled RK4 (``RigidBodies.run``) has its own arithmetic, so the
    block runs the numpy step loop (``RigidBodies.run_reference``) with ``euler_rates``
    replaced by :func:`torque_only`; patching ``euler_rates`` alone changes nothing."""
    from unittest import mock

    from inertia_id.physics import dynamics

    with (
        mock.patch.object(dynamics, "euler_rates", torque_only),
        mock.patch.object(dynamics.RigidBodies, "run", dynamics.RigidBodies.run_reference),
    ):
        yield


# --------------------------------------------------------------------------- the service

#: The API key ``python -m app.serve`` generates, as its banner shows it.
GENERATED_KEY = re.compile(r"^API key:   (\S+)\n\s+\(generated now", re.MULTILINE)


def classifier_row(scenario_id: str, model: Any) -> Any:
    """A ``service.store.models.ClassifierRow`` for a classifier trained here (``model``,
    an ``InertiaClassifier``) under ``scenario_id``, as a train job would store it."""
    from service.store.models import ClassifierRow

    document = model.to_json()
    return ClassifierRow(
        scenario_id=scenario_id,
        metric=model.metric,
        f1=model.f1_,
        accuracy=model.accuracy_,
        sequence=np.asarray(model.sequence_).tolist(),
        candidate_names=list(model.candidate_names_),
        confusion=model.confusion_.tolist(),
        document=document,
        sha256=json.loads(document)["sha256"],
    )


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def service_env(repo: Path) -> dict[str, str]:
    """This process's environment without any inertia-id setting (the machine's
    configuration never reaches the service measured), ``repo`` first on ``PYTHONPATH``
    and the output unbuffered (the log is read while the service runs)."""
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith("INERTIA_ID_") and k not in ("DATABASE_URL", "BROKER_URL")
    }
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(repo), env.get("PYTHONPATH")]))
    env["PYTHONUNBUFFERED"] = "1"
    return env


def spawn_service(
    argv: list[str],
    *,
    log_path: Path,
    cwd: Path,
    env: dict[str, str],
    preexec_fn: Callable[[], None] | None = None,
) -> subprocess.Popen[bytes]:
    """Start ``argv`` (the service) in a session of its own, its output to ``log_path``."""
    with open(log_path, "wb") as log:
        return subprocess.Popen(
            argv,
            cwd=cwd,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            preexec_fn=preexec_fn,
        )


def wait_until_ok(
    client: Any, process: subprocess.Popen[Any], log_path: Path, timeout_s: float = 300
) -> None:
    """Poll the service's ``/health`` (``client``, an ``httpx.Client`` on its base URL)
    until it says "ok" with no worker warming up (a starting worker is listed, warming,
    while its task process imports the core); raise with the service's log if it exits
    or ``timeout_s`` passes."""
    import httpx

    deadline = time.perf_counter() + timeout_s
    while True:
        try:
            health = client.get("/health").json()
            if health["status"] == "ok" and not health["workers"].get("warming"):
                return
        except httpx.TransportError:
            pass
        if time.perf_counter() > deadline or process.poll() is not None:
            raise RuntimeError(log_path.read_text(errors="replace"))
        time.sleep(0.2)


def generated_key(log_path: Path) -> str | None:
    """The API key the service generated, from its banner in ``log_path`` (None: none)."""
    found = GENERATED_KEY.search(log_path.read_text(errors="replace"))
    return found.group(1) if found else None


def stop_service(process: subprocess.Popen[bytes]) -> None:
    """SIGTERM; the whole session SIGKILLed when it is not gone within 60 s."""
    process.send_signal(signal.SIGTERM)
    try:
        process.wait(60)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait(10)


@contextlib.contextmanager
def scratch_postgres(admin_url: str) -> Iterator[str]:
    """The URL of a new, empty PostgreSQL database on the server at ``admin_url`` (named
    ``inertia_id_bench_`` and a random suffix, so a leftover says which made it),
    dropped after, whoever is still connected to it."""
    import uuid

    from sqlalchemy import create_engine, text

    admin = create_engine(admin_url, isolation_level="AUTOCOMMIT")
    name = f"inertia_id_bench_{uuid.uuid4().hex[:12]}"
    with admin.connect() as connection:
        connection.execute(text(f'CREATE DATABASE "{name}"'))
    try:
        yield admin.url.set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()
