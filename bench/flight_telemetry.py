"""Identification on telemetry as a flight team gets it, flown by Basilisk.

The default classifier (marginal likelihood, its default realisations) is trained on our
simulator for ``paper-in-orbit`` and the hand-designed sequence ``[[4,4,4,0,0,0]]*4``.
Every test series is flown by Basilisk (an independent simulator, ``bsk``) at 100 Hz from
``--pre-start-s`` (30) s before the sequence start, with a residual initial rate of
``--rate-min``..``--rate-max`` deg/s (0.1-0.5) in a random direction (the body then
drifts under the disturbance torque until the start) and the scenario's gyro bias, and
then written out the way a flight team's ground segment exports it:

- the gyro at the case's rate (1, 5, 10 or 20 Hz), its ticks at a random phase against
  the sequence's steps (every 100 Hz sample a tick could fall on, not a grid time);
- stamps in the spacecraft's clock, the sequence starting at ``--clock`` (7.6e8) s plus a
  random fraction of a second, written with 6 decimals, or as ISO-8601 UTC strings;
- rates in rad/s, or in deg/s under a ``wx_deg_s`` header;
- a CSV text, read by ``parse_telemetry`` with the sequence start given beside it, as
  ``inertia-id identify --sequence-start`` and ``POST /identify`` read it.

Cases (``--series`` draws each, the five candidates in turn): the gyro at 1, 5, 10 and
20 Hz; ISO stamps, as calendar dates and as days of the year
(``2026-341T12:00:00.050Z``); deg/s; a 1 s dropout inside the sequence; no telemetry
before the start (10 and 1 Hz); the start known only roughly (the one stated off the
true one by up to ±``--within``/2 s, searched within ±``--within`` s:
``identify(..., estimate_start_within_s=--within)``); and two bodies that are none of
the candidates: the candidate's tensor scaled by 1.3, and every thruster 10 % weaker
than stated; and the start stated 20 s before the thrusters fired (the 4 s after it quiet).
Per case: identified right, identified wrong (at 0.99, the default), ambiguous, matches
none, not this sequence and refused, each as a share with its Wilson 95 %
interval, and the highest confidence of a wrong name. For the genuine cases a
matches-none is a false alarm; for the two off-candidate bodies it is the right answer
and any name is wrong. Then what the reader says of a duplicated stamp, stamps out of
order and a NaN row (one series each).

Run: OPENBLAS_NUM_THREADS=1 python bench/flight_telemetry.py [--series 50] [--cases ...]
(about 10 minutes at 50 series a case on the 2-core machine, most of it Basilisk)
"""

from __future__ import annotations

import time
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, begin, print_table, write_json

from inertia_id import Scenario
from inertia_id.classifiers.registry import DEFAULT_KIND, kind_class, train_classifier
from inertia_id.cli.options import one_line
from inertia_id.evaluation.identify import identify
from inertia_id.evaluation.sweep import wilson_interval
from inertia_id.evaluation.telemetry import parse_telemetry
from inertia_id.physics.engines.basilisk import basilisk_available, simulate_basilisk
from inertia_id.physics.presets import preset

FLY_HZ = 100
ISO_ORIGIN = datetime(2026, 12, 7, 12, 0, 0, tzinfo=UTC)

#: name: (gyro Hz, stamps, unit, body, dropout, pre-start, start search)
CASES: dict[str, dict[str, Any]] = {
    "1 Hz": {"rate": 1},
    "5 Hz": {"rate": 5},
    "10 Hz": {"rate": 10},
    "20 Hz": {"rate": 20},
    "10 Hz ISO stamps": {"rate": 10, "stamps": "iso"},
    "10 Hz day-of-year stamps": {"rate": 10, "stamps": "doy"},
    "10 Hz deg/s": {"rate": 10, "unit": "deg"},
    "10 Hz 1 s dropout": {"rate": 10, "dropout": True},
    "10 Hz none before start": {"rate": 10, "pre_start": False},
    "1 Hz none before start": {"rate": 1, "pre_start": False},
    "10 Hz start within": {"rate": 10, "within": True},
    "10 Hz start stated 20 s early": {"rate": 10, "early_s": 20.0},
    "10 Hz inertia x1.3": {"rate": 10, "body": "inertia"},
    "10 Hz thrust x0.9": {"rate": 10, "body": "thrust"},
}


def truth(scenario: Scenario, body: str) -> Scenario:
    """The scenario flown: as stated, every candidate's tensor scaled by 1.3, or every
    thruster 10 % weaker than stated."""
    if body == "genuine":
        return scenario
    document = scenario.model_dump()
    if body == "inertia":
        document["candidate_generator"] = None
        for candidate in document["inertia_candidates"]:
            candidate["inertia_kg_m2"] = (1.3 * np.asarray(candidate["inertia_kg_m2"])).tolist()
    else:
        matrix = np.asarray(document["thrusters"]["torque_matrix_nm"])
        document["thrusters"]["torque_matrix_nm"] = (0.9 * matrix).tolist()
    return Scenario.model_validate(document)


def initial_rate(rng: np.random.Generator, low_deg: float, high_deg: float) -> np.ndarray:
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    return np.radians(rng.uniform(low_deg, high_deg)) * direction


def export(
    times: np.ndarray, omega: np.ndarray, start: float, stamps: str, unit: str
) -> tuple[str, float | str]:
    """The CSV a ground segment writes (stamps in the spacecraft's clock or ISO-8601 UTC,
    rates in rad/s or deg/s) and the sequence start in the same clock."""
    if unit == "deg":
        header, rates = "time_s,wx_deg_s,wy_deg_s,wz_deg_s", np.degrees(omega)
    else:
        header, rates = "time_s,wx_rad_s,wy_rad_s,wz_rad_s", omega
    if stamps in ("iso", "doy"):
        # ISO 8601 in UTC: the calendar date, or the day of the year (CCSDS ASCII B).
        form = "%Y-%m-%dT%H:%M:%S.%fZ" if stamps == "iso" else "%Y-%jT%H:%M:%S.%fZ"
        header = header.replace("time_s", "time_utc")
        origin = ISO_ORIGIN + timedelta(microseconds=round(start % 1.0 * 1e6))
        cells = [(origin + timedelta(microseconds=round(t * 1e6))).strftime(form) for t in times]
        stated: float | str = origin.strftime(form)
    else:
        cells = [f"{start + t:.6f}" for t in times]
        stated = float(f"{start:.6f}")
    lines = [header] + [
        f"{c},{w[0]:.9g},{w[1]:.9g},{w[2]:.9g}" for c, w in zip(cells, rates, strict=True)
    ]
    return "\n".join(lines) + "\n", stated


def fly(
    scenario: Scenario,
    case: dict[str, Any],
    k: int,
    rng: np.random.Generator,
    args: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """One Basilisk series of candidate ``k`` as the gyro gives it: (seconds from the true
    start, rad/s), ticks at the case's rate and a random phase."""
    coast = round(args.pre_start_s / scenario.timing.step_duration_s)
    flown = [[0] * scenario.n_thrusters] * coast + [list(r) for r in GOOD_SEQUENCE]
    omega0 = initial_rate(rng, args.rate_min, args.rate_max)
    series = simulate_basilisk(
        scenario, flown, k, rng, sample_rate_hz=FLY_HZ, initial_rate_rad_s=omega0
    )
    t = series.time_s - coast * scenario.timing.step_duration_s
    every = FLY_HZ // case["rate"]
    phase = int(rng.integers(every))
    keep = np.arange(phase, len(t), every)
    t, omega = t[keep], series.omega_measured[keep]
    if not case.get("pre_start", True):
        after = t > 0.0
        t, omega = t[after], omega[after]
    if case.get("dropout"):
        hole = rng.uniform(0.5, len(GOOD_SEQUENCE) - 1.5)
        lost = (t > hole) & (t < hole + 1.0)
        t, omega = t[~lost], omega[~lost]
    return t, omega


def outcome(verdict: Any, k: int, genuine: bool) -> str:
    if verdict.status == "identified":
        return "right" if genuine and verdict.candidate_index == k else "wrong"
    if verdict.status == "ambiguous":
        return "ambiguous"
    return "none" if verdict.status == "matches-none" else "not this sequence"


def run_case(
    name: str, case: dict[str, Any], model: Any, scenario: Scenario, args: Any, seed: int
) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    body = case.get("body", "genuine")
    flown_scenario = truth(scenario, body)
    counts = dict.fromkeys(("right", "wrong", "ambiguous", "none", "not this sequence"), 0)
    counts["refused"] = 0
    wrong_confidence: list[float] = []
    refusals: list[str] = []
    started = time.perf_counter()
    for draw in range(args.series):
        k = draw % len(scenario.candidate_names)
        t, omega = fly(flown_scenario, case, k, rng, args)
        start = args.clock + float(rng.uniform(0.0, 1.0))
        text, stated = export(t, omega, start, case.get("stamps", "clock"), case.get("unit", "rad"))
        within = None
        if case.get("early_s"):
            # The start stated before the thrusters fired: the pass shows no response.
            stated = float(f"{start - case['early_s']:.6f}")
        if case.get("within"):
            # The start is known only within the window: the one stated is off the true
            # one by up to half of it, either way (the stamps are the clock's, as sent).
            within = args.within
            stated = float(f"{start + rng.uniform(-0.5, 0.5) * args.within:.6f}")
        try:
            telemetry = parse_telemetry(text, fmt="csv", sequence_start=stated)
            verdict = identify(model, telemetry, estimate_start_within_s=within)
        except ValueError as exc:  # InputError, or pydantic's ValidationError wrapping it
            counts["refused"] += 1
            refusals.append(one_line(exc))
            continue
        result = outcome(verdict, k, body == "genuine")
        counts[result] += 1
        if result == "wrong":
            wrong_confidence.append(verdict.confidence)
    return {
        "case": name,
        "body": body,
        "counts": counts,
        "wrong_confidence_max": max(wrong_confidence) if wrong_confidence else None,
        "refusals": refusals[:3],
        "seconds": time.perf_counter() - started,
    }


def share(count: int, n: int) -> str:
    low, high = wilson_interval(count, n)
    return f"{count / n:.0%} [{low:.0%}, {high:.0%}]"


def anomalies(scenario: Scenario, args: Any) -> list[list[str]]:
    """What the reader says of a duplicated stamp, stamps out of order and a NaN row."""
    rng = np.random.default_rng(args.seed + 99)
    t, omega = fly(scenario, {"rate": 10}, 0, rng, args)
    text, stated = export(t, omega, args.clock + 0.25, "clock", "rad")
    lines = text.splitlines()
    edits = {
        "duplicated stamp (a row sent twice)": [*lines[:200], lines[199], *lines[200:]],
        "stamps out of order (two rows swapped)": [
            *lines[:200],
            lines[201],
            lines[200],
            *lines[202:],
        ],
        "NaN row": [*lines[:200], lines[200].split(",")[0] + ",nan,nan,nan", *lines[201:]],
    }
    rows = []
    for label, edited in edits.items():
        try:
            telemetry = parse_telemetry("\n".join(edited), fmt="csv", sequence_start=stated)
            said = f"accepted: {identify(model_cache[0], telemetry).status}"
        except ValueError as exc:  # InputError, or pydantic's ValidationError wrapping it
            said = f"refused: {one_line(exc)}"
        rows.append([label, said])
    return rows


model_cache: list[Any] = []


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=50, help="draws per case")
    parser.add_argument(
        "--cases", default=",".join(CASES), help=f"comma-separated, of: {', '.join(CASES)}"
    )
    parser.add_argument("--pre-start-s", type=float, default=30.0)
    parser.add_argument("--rate-min", type=float, default=0.1, help="deg/s")
    parser.add_argument("--rate-max", type=float, default=0.5, help="deg/s")
    parser.add_argument("--clock", type=float, default=7.6e8, help="spacecraft clock, s")
    parser.add_argument("--within", type=float, default=1.0, help="start window, s")
    args = begin(parser, "Identification on flight-team telemetry flown by Basilisk")
    if not basilisk_available():
        raise SystemExit("Basilisk is not installed: pip install 'inertia-id[basilisk]'")
    chosen = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in chosen if c not in CASES]
    if unknown:
        raise SystemExit(f"unknown case(s) {unknown}; the cases are {list(CASES)}")
    scenario = preset("paper-in-orbit")
    started = time.perf_counter()
    n_train = kind_class(DEFAULT_KIND).DEFAULT_REALISATIONS
    model = train_classifier(scenario, GOOD_SEQUENCE, n_train, np.random.default_rng(args.seed))
    model_cache.append(model)
    print(
        f"classifier {model.kind}, {n_train} realisations a candidate, trained in "
        f"{time.perf_counter() - started:.1f} s; {args.series} series a case\n",
        flush=True,
    )
    results = []
    for i, name in enumerate(chosen):
        result = run_case(name, CASES[name], model, scenario, args, args.seed + 1 + i)
        results.append(result)
        c, n = result["counts"], args.series
        print(
            f"{name}: {c} (wrong at up to {result['wrong_confidence_max']}) in "
            f"{result['seconds']:.0f} s",
            flush=True,
        )
        for said in result["refusals"]:
            print(f"    refused: {said}")
    rows = []
    for result in results:
        c, n = result["counts"], args.series
        top = result["wrong_confidence_max"]
        rows.append(
            [
                result["case"],
                result["body"],
                share(c["right"], n),
                share(c["wrong"], n),
                share(c["ambiguous"], n),
                share(c["none"], n),
                share(c["not this sequence"], n),
                share(c["refused"], n),
                "-" if top is None else f"{top:.4f}",
            ]
        )
    print()
    print_table(
        [
            "case",
            "body",
            "identified right",
            "identified wrong",
            "ambiguous",
            "matches none",
            "not this sequence",
            "refused",
            "wrong at most",
        ],
        rows,
    )
    print()
    odd = anomalies(scenario, args)
    print_table(["telemetry", "what identify said"], odd)
    write_json(args.json, args, {"cases": results, "anomalies": odd})


if __name__ == "__main__":
    main()
