"""The cost of refusing a JSON key given twice: ``loads_unique_keys`` against ``json.loads``.

Every JSON a user sends or hands over is read with
:func:`inertia_id.checks.loads_unique_keys` (``json.loads`` with an ``object_pairs_hook``
that counts each object's keys). This prints, side by side:

- the parse alone, on the bodies the API takes (``POST /identify`` with 80 samples, the
  size of the latency benchmark's, and with 20,000; ``POST /scenarios`` with the paper
  preset's document) and, for scale, a stored classifier document (the service's own,
  which is read with ``json.loads`` still);
- ``POST /identify`` in process (FastAPI's test client, SQLite, the verdict on the
  compute threads, a euclidean classifier of the paper preset), with the body parsed by
  each in turn.

The two readers are timed in alternating rounds (best of ``--repeats`` calls each per
round, each reader first in every other round), so that a change in the machine's load
falls on both; the medians over ``--rounds`` are printed. Takes about 30 s:
``python bench/json_keys.py``.
"""

from __future__ import annotations

import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from _common import (
    GOOD_SEQUENCE,
    base_parser,
    begin,
    best_of,
    classifier_row,
    positive_int,
    print_table,
    write_json,
)

from inertia_id.checks import loads_unique_keys

READERS: dict[str, Callable[[Any], Any]] = {
    "json.loads": json.loads,
    "loads_unique_keys": loads_unique_keys,
}


def _telemetry_body(classifier_id: str, samples: int) -> bytes:
    rng = np.random.default_rng(0)
    telemetry = {
        "time_s": [round(0.05 * (i + 1), 6) for i in range(samples)],
        "omega_rad_s": rng.normal(0.0, 0.01, (samples, 3)).round(9).tolist(),
    }
    return json.dumps({"classifier_id": classifier_id, "telemetry": telemetry}).encode()


def _alternate(work: Callable[[Callable[[Any], Any]], Callable[[], Any]], args: Any) -> list[float]:
    """Median seconds per call for each reader, timed in alternating rounds."""
    best: dict[str, list[float]] = {name: [] for name in READERS}
    for round_ in range(args.rounds):
        # Each reader goes first in every other round: the first of a pair ran slower.
        order = list(READERS.items())
        for name, reader in order if round_ % 2 == 0 else order[::-1]:
            seconds, _, _ = best_of(work(reader), args.repeats)
            best[name].append(seconds)
    return [statistics.median(best[name]) for name in READERS]


def _parse_rows(bodies: dict[str, bytes], args: Any) -> list[list[Any]]:
    rows = []
    for label, body in bodies.items():
        plain, unique = _alternate(lambda reader, body=body: lambda: reader(body), args)
        rows.append([label, len(body), plain * 1e6, unique * 1e6, unique / plain])
    return rows


def _in_process(args: Any) -> tuple[list[list[Any]], dict[str, bytes]]:
    import warnings

    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

    import app.api.identify
    from app.main import create_app
    from inertia_id import Scenario, train
    from service.config import Settings

    data_dir = Path(tempfile.mkdtemp(prefix="json-keys-"))
    settings = Settings(
        INERTIA_ID_DATA_DIR=data_dir,
        DATABASE_URL=f"sqlite:///{data_dir / 'bench.db'}",
        BROKER_URL="filesystem://",
        INERTIA_ID_API_KEY=None,
        INERTIA_ID_VERDICT_PROCESS="off",
        INERTIA_ID_ALLOWED_HOSTS="testserver",
    )
    api = create_app(settings)
    headers = {"X-API-Key": api.state.generated_api_key, "content-type": "application/json"}
    paper = Scenario.paper()
    scenario_body = json.dumps({"scenario": paper.model_dump(mode="json")}).encode()
    with TestClient(api) as client:
        created = client.post("/scenarios", content=scenario_body, headers=headers)
        model = train(paper, GOOD_SEQUENCE, 10, np.random.default_rng(1), metric="euclidean")
        row = classifier_row(created.json()["id"], model)
        with api.state.db.session() as session:
            session.add(row)
            session.flush()
            classifier_id = row.id
        body = _telemetry_body(classifier_id, 80)

        def post(reader: Callable[[Any], Any]) -> Callable[[], Any]:
            def one() -> None:
                app.api.identify.loads_unique_keys = reader  # type: ignore[attr-defined]
                response = client.post("/identify", content=body, headers=headers)
                assert response.status_code == 200, response.text

            return one

        post(json.loads)()  # the classifier loaded and cached, the kernels warm
        start = time.perf_counter()
        plain, unique = _alternate(post, args)
        print(f"(in-process rounds took {time.perf_counter() - start:.1f} s)")
        app.api.identify.loads_unique_keys = loads_unique_keys  # type: ignore[attr-defined]
    rows = [["POST /identify, 80 samples", len(body), plain * 1e6, unique * 1e6, unique / plain]]
    bodies = {
        "identify body, 80 samples": body,
        "identify body, 20,000 samples": _telemetry_body(classifier_id, 20_000),
        "POST /scenarios body (paper)": scenario_body,
        "stored classifier document (euclidean)": row.document.encode(),
    }
    return rows, bodies


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=positive_int, default=7, help="alternating rounds")
    parser.add_argument("--repeats", type=positive_int, default=20, help="calls a round (best)")
    args = begin(parser, "Refusing a JSON key given twice: the cost")
    request_rows, bodies = _in_process(args)
    parse_rows = _parse_rows(bodies, args)
    headers = ["what", "bytes", "json.loads µs", "loads_unique_keys µs", "ratio"]
    print_table(headers, parse_rows, "the parse alone (median of the rounds' best)")
    print_table(headers, request_rows, "a request in process (median of the rounds' best)")
    write_json(
        args.json,
        args,
        {"parse": parse_rows, "request": request_rows, "headers": headers},
    )


if __name__ == "__main__":
    main()
