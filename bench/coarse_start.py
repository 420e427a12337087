"""The start search on a coarse grid: a true start a fraction of a grid period off the
stated one, found by the parabola through the grid's scores (before) and by scoring the
starts between the grid's where the grid is coarse for the response (now), side by side
on the same series.

Per configuration: ``paper-in-orbit`` modelled at 1 Hz with 2 s steps (the ground
segment's model, as ``bench/fast_telemetry.py``) flown with fire then brake,
``[[4,4,4,0,0,0]]*2 + [[0,0,0,4,4,4]]*2``, and as the control the preset's own 20 Hz grid
with 1 s steps and the hand-designed sequence; the default classifier trained at 1x
noise on our simulator. Test series from our simulator at ``--process`` times the
process noise, with 30 s of telemetry before the start, flown at 10 Hz (100 Hz for the
control) and cut to each gyro rate: on the 1 Hz grid each ``--offsets`` s (every other
series early, the others late) between the stated start and the true one, the stamps
ticking on the stated start's clock (a 1 Hz gyro's samples then fall that far off the
true start's grid times); on the 20 Hz grid the true start drawn uniformly within
±``--control-offset`` s, the stamps on the true start's clock (a random phase against
the stated start's grid). Each series judged by ``identify(...,
estimate_start_within_s=W)`` for each ``--within`` W (the 1 Hz rows; the control
searches ±0.3 s).

Per row, before and now: the share named right (most probable), identified right at the
default confidence and false alarms (a genuine series called matches-none or
not-this-sequence), each with its Wilson 95 % interval, the |start error| median / 90th
percentile / largest (s), and identify's median CPU time with the search (ms). "before"
is the same code with the coarse-grid branch off
(``identify.COARSE_GRID_RISE = inf``: the parabola alone, as before this change).

Beyond that configuration (the defaults): ``--preset`` (``paper``: from rest, an
unbiased gyro; ``canted``: the paper timing with eight canted thrusters and five
full-tensor candidates, ``bench/telemetry_identify.py``'s), ``--sequence``
(``fire-brake``, ``hand-designed`` for the scenario's geometry, the engine tests'
mixed-duty ``canted`` one, or rows as JSON), ``--grid-hz`` and ``--step-s`` (the
classifier's grid and steps), ``--pre-start-s`` (0: no sample before the true start),
``--fly-hz`` (the rate the series are flown at; the offsets then in its periods) and
``--engine basilisk`` (the test series flown by Basilisk, an independent simulator).
``--show-rise`` prints, per row, how many series "now" took as coarse (the rule's rise
above ``COARSE_GRID_RISE``) and the rises' least / median / largest: a grid whose rises
straddle the threshold is borderline, its decision flipping series by series.

Run: OPENBLAS_NUM_THREADS=1 python bench/coarse_start.py [--n 20] [--within 1,2]
(about 2 minutes on the 2-core machine)
"""

from __future__ import annotations

import json
import math
import time
from typing import Any
from unittest import mock

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, begin, float_list, print_table, write_json
from telemetry_identify import FLAGGED, canted_paper

from inertia_id import Scenario
from inertia_id.classifiers.registry import DEFAULT_KIND, kind_class, train_classifier
from inertia_id.cli.scenario import _at_rate
from inertia_id.evaluation import identify as identify_module
from inertia_id.evaluation.identify import identify
from inertia_id.evaluation.sweep import wilson_interval
from inertia_id.evaluation.telemetry import Telemetry
from inertia_id.physics.engines.basilisk import (
    CANTED_SEQUENCE,
    basilisk_available,
    simulate_basilisk,
)
from inertia_id.physics.presets import preset
from inertia_id.physics.sequences import hand_designed
from inertia_id.physics.simulate import simulate

FIRE_BRAKE = [[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2
CONTROL_WITHIN_S = 0.3


def _scenario(name: str, timing: dict | None = None) -> Scenario:
    """The ``--preset`` scenario, with ``timing`` overriding its own where given."""
    if name == "canted":
        scenario = canted_paper()
        if timing is None:
            return scenario
        data = scenario.model_dump()
        data["timing"] = {**data["timing"], **timing}
        return Scenario.model_validate(data)
    return preset(name) if timing is None else preset(name, timing=timing)


def _grid_timing(args: Any) -> dict:
    """The classifier's grid: ``--grid-hz`` samples, ``--step-s`` steps, integrated at
    0.01 s (as ``bench/fast_telemetry.py``)."""
    return {
        "step_duration_s": args.step_s,
        "integration_step_s": 0.01,
        "sample_rate_hz": args.grid_hz,
    }


def _sequence(text: str, scenario: Scenario) -> list[list[int]]:
    """The ``--sequence`` rows for ``scenario``, checked against its thrusters."""
    if text == "fire-brake":
        rows = FIRE_BRAKE
    elif text == "hand-designed":
        rows = hand_designed(scenario, 4).tolist()
    elif text == "canted":
        rows = CANTED_SEQUENCE
    else:
        rows = json.loads(text)
    scenario.check_sequence(rows)
    return [list(map(int, row)) for row in rows]


def _share(hits: int, n: int) -> str:
    low, high = wilson_interval(hits, n)
    return f"{hits / n:.2f} [{low:.2f}, {high:.2f}]"


def _flights(
    scenario: Any, sequence: Any, n: int, args: Any, fly_rate: float, rng: Any
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` series a candidate flown at ``fly_rate`` Hz with ``args.pre_start_s`` of
    quiet before the sequence and a step after, by ``args.engine``: stamps in s from the
    true start, (K, n, T, 3) rates."""
    step = scenario.timing.step_duration_s
    coast = round(args.pre_start_s / step)
    quiet = [[0] * scenario.n_thrusters]
    flown_sequence = quiet * coast + sequence + quiet
    if args.engine == "basilisk":
        runs = [
            [
                simulate_basilisk(
                    scenario,
                    flown_sequence,
                    k,
                    rng,
                    sample_rate_hz=fly_rate,
                    process_noise_scale=args.process,
                )
                for _ in range(n)
            ]
            for k in range(scenario.n_candidates)
        ]
        t = np.asarray(runs[0][0].time_s)
        omega = np.array([[np.asarray(r.omega_measured) for r in row] for row in runs])
        return t - coast * step, omega
    flown = simulate(
        _at_rate(scenario, fly_rate),
        flown_sequence,
        n,
        rng,
        process_noise_scale=args.process,
    )
    return np.asarray(flown.time_s) - coast * step, np.asarray(flown.omega_measured)


def _cut(t: np.ndarray, rate: float, phase: float) -> np.ndarray:
    """The samples of a ``rate`` Hz gyro whose stamps lie ``phase`` s past whole sample
    periods of ``t``'s clock."""
    period = 1.0 / rate
    return np.isclose(np.mod(t - phase + period / 2, period), period / 2, atol=1e-6)


def _judge(model: Any, cases: list[tuple[int, Telemetry, float]], within: float) -> dict:
    """Each case (candidate, telemetry, stated start less the true one, s) judged before
    and now; the figures of each."""
    figures = {}
    original = identify_module._neighbours_rise
    for name, rise in (("before", math.inf), ("now", identify_module.COARSE_GRID_RISE)):
        named = identified = flagged = 0
        errors, cpu, rises = [], [], []
        seen: list[float] = []

        def recorded(*a: Any, _seen: list = seen, **kw: Any) -> float:
            value = original(*a, **kw)
            _seen.append(value)
            return value

        with (
            mock.patch.object(identify_module, "COARSE_GRID_RISE", rise),
            mock.patch.object(identify_module, "_neighbours_rise", recorded),
        ):
            for k, telemetry, off in cases:
                del seen[:]
                started = time.process_time()
                verdict = identify(model, telemetry, estimate_start_within_s=within)
                cpu.append(time.process_time() - started)
                # The rule's rise where the search asked it (the last such call).
                rises.append(seen[-1] if seen else math.nan)
                named += verdict.candidate_index == k
                identified += verdict.status == "identified" and verdict.candidate_index == k
                flagged += verdict.status in FLAGGED
                errors.append(abs(off + verdict.sequence_start_shift_s))
        figures[name] = {
            "series": len(cases),
            "named": named,
            "identified": identified,
            "false_alarms": flagged,
            "start_error_s": [
                float(np.median(errors)),
                float(np.quantile(errors, 0.9)),
                float(max(errors)),
            ],
            "cpu_ms_median": 1e3 * float(np.median(cpu)),
            "rises": rises,
        }
    return figures


def _rows(label: str, figures: dict) -> list[list[Any]]:
    rows = []
    for name in ("before", "now"):
        f = figures[name]
        n = f["series"]
        median, p90, largest = f["start_error_s"]
        rows.append(
            [
                label,
                name,
                _share(f["named"], n),
                _share(f["identified"], n),
                _share(f["false_alarms"], n),
                f"{median:.3f} / {p90:.3f} / {largest:.3f}",
                f"{f['cpu_ms_median']:.1f}",
            ]
        )
    return rows


def coarse(args: Any, rng: np.random.Generator) -> tuple[list, dict]:
    scenario = _scenario(args.preset, _grid_timing(args))
    sequence = _sequence(args.sequence, scenario)
    model = train_classifier(scenario, sequence, kind_class(DEFAULT_KIND).DEFAULT_REALISATIONS, rng)
    t, omega = _flights(scenario, sequence, args.n, args, args.fly_hz, rng)
    rows, figures = [], {}
    for rate in args.rates:
        for offset in args.offsets:
            cases = []
            for k in range(scenario.n_candidates):
                for i in range(args.n):
                    # The stated start less the true one: early and late in turn.
                    off = offset if (i + k) % 2 == 0 else -offset
                    keep = _cut(t, rate, off)
                    cases.append(
                        (
                            k,
                            Telemetry(
                                time_s=t[keep].tolist(),
                                omega_rad_s=omega[k, i][keep].tolist(),
                                sequence_start=off,
                            ),
                            off,
                        )
                    )
            for within in args.within:
                label = (
                    f"{args.grid_hz:g} Hz grid, {rate:g} Hz gyro, start ±{offset:g} s off, "
                    f"search ±{within:g} s"
                )
                found = _judge(model, cases, within)
                figures[label] = found
                rows += _rows(label, found)
    return rows, figures


def control(args: Any, rng: np.random.Generator) -> tuple[list, dict]:
    scenario = _scenario(args.preset)
    sequence = GOOD_SEQUENCE if args.preset != "canted" else hand_designed(scenario, 4).tolist()
    model = train_classifier(scenario, sequence, kind_class(DEFAULT_KIND).DEFAULT_REALISATIONS, rng)
    t, omega = _flights(scenario, sequence, args.n, args, 100.0, rng)
    keep = _cut(t, 20.0, 0.0)
    cases = []
    for k in range(scenario.n_candidates):
        for i in range(args.n):
            off = float(rng.uniform(-args.control_offset, args.control_offset))
            telemetry = Telemetry(
                time_s=t[keep].tolist(), omega_rad_s=omega[k, i][keep].tolist(), sequence_start=off
            )
            cases.append((k, telemetry, off))
    label = (
        f"20 Hz grid, 20 Hz gyro, start within ±{args.control_offset:g} s, "
        f"search ±{CONTROL_WITHIN_S:g} s"
    )
    found = _judge(model, cases, CONTROL_WITHIN_S)
    return _rows(label, found), {label: found}


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20, help="series per candidate per row")
    parser.add_argument(
        "--offsets", type=float_list, default=[0.2, 0.4, 0.5], help="true start this far off, s"
    )
    parser.add_argument("--rates", type=float_list, default=[1.0, 10.0], help="gyro rates, Hz")
    parser.add_argument("--within", type=float_list, default=[1.0, 2.0], help="search ±s")
    parser.add_argument(
        "--control-offset", type=float, default=0.15, help="20 Hz control's true start within ±s"
    )
    parser.add_argument("--process", type=float, default=1.0, help="process noise multiple")
    parser.add_argument("--no-control", action="store_true", help="skip the 20 Hz control")
    parser.add_argument(
        "--preset",
        choices=("paper-in-orbit", "paper", "canted"),
        default="paper-in-orbit",
        help="scenario (canted: paper timing, canted thrusters, full tensors)",
    )
    parser.add_argument(
        "--sequence",
        default="fire-brake",
        help="fire-brake, hand-designed, canted (the engine tests' mixed duty) or JSON rows",
    )
    parser.add_argument("--grid-hz", type=float, default=1.0, help="classifier's grid, Hz")
    parser.add_argument("--step-s", type=float, default=2.0, help="actuation step, s")
    parser.add_argument(
        "--pre-start-s", type=float, default=30.0, help="telemetry before the true start, s"
    )
    parser.add_argument("--fly-hz", type=float, default=10.0, help="series flown at, Hz")
    parser.add_argument(
        "--engine", choices=("numpy", "basilisk"), default="numpy", help="flies the test series"
    )
    parser.add_argument(
        "--show-rise", action="store_true", help="print the coarse-grid rule's rises per row"
    )
    args = begin(parser, "Start search on a coarse grid")
    if args.engine == "basilisk" and not basilisk_available():
        parser.error("--engine basilisk: Basilisk does not import here")
    for flag, value in (
        ("--grid-hz", args.grid_hz),
        ("--step-s", args.step_s),
        ("--fly-hz", args.fly_hz),
    ):
        if not (math.isfinite(value) and value > 0):
            parser.error(f"{flag}: give a positive number, got {value:g}")
    if args.pre_start_s < 0:
        parser.error(f"--pre-start-s: give 0 or more, got {args.pre_start_s:g}")
    per = [args.fly_hz / r for r in args.rates]
    if not all(abs(p - round(p)) < 1e-9 and round(p) >= 1 for p in per):
        parser.error(
            f"--rates: the series are flown at {args.fly_hz:g} Hz: give rates that divide it, "
            f"got {args.rates}"
        )
    ticks = [o * args.fly_hz for o in args.offsets]
    if not all(
        0.0 < o < 1.0 and abs(x - round(x)) < 1e-9 for o, x in zip(args.offsets, ticks, strict=True)
    ):
        parser.error(
            f"--offsets: whole periods of the {args.fly_hz:g} Hz flight between 0 and 1 s, "
            f"got {args.offsets}"
        )
    try:
        grid = _scenario(args.preset, _grid_timing(args))
    except ValueError as error:
        parser.error(f"--grid-hz {args.grid_hz:g} / --step-s {args.step_s:g}: {error}")
    try:
        _sequence(args.sequence, grid)
    except (ValueError, TypeError) as error:
        parser.error(f"--sequence {args.sequence!r}: {error}")
    try:
        _at_rate(grid, args.fly_hz)
    except ValueError as error:
        parser.error(f"--fly-hz {args.fly_hz:g}: {error}")
    rng = np.random.default_rng(args.seed)
    started = time.perf_counter()
    rows, figures = coarse(args, rng)
    if not args.no_control:
        more, found = control(args, rng)
        rows += more
        figures.update(found)
    print_table(
        [
            "telemetry",
            "search",
            "named right",
            "identified right at 0.99",
            "false alarms",
            "|start error| s: median / 90th / largest",
            "CPU ms",
        ],
        rows,
        title=f"default classifier, {args.process:g}x process noise, {args.n} series a candidate",
    )
    if args.show_rise:
        for label, found in figures.items():
            rises = np.asarray(found["now"]["rises"], dtype=float)
            finite = rises[np.isfinite(rises)]
            coarse_n = int(np.sum(finite > identify_module.COARSE_GRID_RISE))
            spread = (
                f"{finite.min():.1f} / {np.median(finite):.1f} / {finite.max():.1f}"
                if finite.size
                else "none asked"
            )
            print(f"{label}: coarse {coarse_n} of {rises.size}; rise least/median/largest {spread}")
    print(f"total {time.perf_counter() - started:.0f} s")
    write_json(args.json, args, {"rows": figures})


if __name__ == "__main__":
    main()
