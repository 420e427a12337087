"""Telemetry faster than the classifier's grid, or off it: a 5 to 50 Hz gyro, or a 1 Hz
gyro whose stamps are not the grid's, against a classifier modelled at 1 Hz (the ground
segment's rate) or at 20 Hz; identify told of the sequence's breaks against identify told
of none (what it did before), side by side on the same series.

A gyro sample is the rate at its stamp; telemetry faster than the grid is put on it a
cell (one grid period) per grid time. The cell's mean is off the rate at the grid time
wherever the slope breaks inside the cell (a thruster switching at a step boundary): by
about a quarter of the half cell times the change of slope, an eighth of a second's
angular acceleration on a 1 Hz grid. Since this change identify fits such a cell with a
line plus the break's low-pass ramp (``inertia_id.evaluation.telemetry.ResponseShape``).
Telemetry at the grid's rate but off it (a 1 Hz gyro whose clock is not the sequence's:
stamps 0.3 or 0.5 s past the grid times) is read at each grid time by interpolating
between the samples around it, off by up to a quarter of a second's change of slope where
a thruster switches between them; since this change the likelihood leaves such grid times
out. "before" below is the same code told of no break, which is what it did before. The
off-grid series are flown at 10 Hz (50 Hz for 0.52 s) and cut to one sample a second.

Per configuration (``paper-in-orbit`` with the grid rate and step length given, 30 s
of telemetry before the start, flown with ``--sequence``: by default fire then brake,
``[[4,4,4,0,0,0]]*2 + [[0,0,0,4,4,4]]*2``, which ends at rest and whose slope breaks
inside the sequence where the thrusters reverse; the hand-designed sequence breaks only
at its ends, where no cell of a 1 Hz grid holds samples on both sides): the default classifier
trained at 1x noise on our simulator; test series flown by Basilisk at each gyro rate
(our own simulator if Basilisk does not import, said so), ``--n`` a candidate; the share
named right (most probable), identified at the default confidence, and false alarms (a
genuine series called matches-none or not-this-sequence), each with its Wilson 95 %
interval.

Run: python bench/fast_telemetry.py [--n 20] (about 3 minutes on the 2-core machine)
"""

from __future__ import annotations

import contextlib
import time
from typing import Any
from unittest import mock

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, int_list, print_header, print_table, write_json
from telemetry_identify import FLAGGED, _fly

from inertia_id.classifiers.registry import DEFAULT_KIND, kind_class, train_classifier
from inertia_id.evaluation import identify as identify_module
from inertia_id.evaluation.identify import DEFAULT_PRE_START_WINDOW_S, identify
from inertia_id.evaluation.sweep import wilson_interval
from inertia_id.evaluation.telemetry import ResponseShape
from inertia_id.physics.engines.basilisk import basilisk_available
from inertia_id.physics.presets import preset

SEQUENCES = {
    "fire-brake": [[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2,
    "hand-designed": GOOD_SEQUENCE,
}
#: (grid rate Hz, step s, gyros as (rate Hz, stamps' offset from the grid s)): the ground
#: segment's 1 Hz model with 2 s steps (8 grid times), and the preset's own 20 Hz grid
#: with 1 s steps (0.52 s: 20 ms off its grid).
CONFIGURATIONS = (
    (1.0, 2.0, ((5, 0.0), (10, 0.0), (50, 0.0), (1, 0.3), (1, 0.5))),
    (20.0, 1.0, ((50, 0.0), (200, 0.0), (1, 0.52))),
)


def _no_breaks(scenario: Any, sequence: Any) -> ResponseShape:
    """The shape told of no break: every cell averaged and every grid time read between
    samples judged, as before."""
    return ResponseShape((), float(scenario.uncertainty.lowpass_time_constant_s))


def _share(hits: int, n: int) -> str:
    low, high = wilson_interval(hits, n)
    return f"{hits / n:.3f} [{low:.2f}, {high:.2f}]"


def _fly_off_grid(
    scenario: Any, sequence: Any, k: int, rng: np.random.Generator, offset_s: float, engine: str
) -> Any:
    """One series at 1 Hz with its stamps ``offset_s`` past whole seconds: flown faster
    and cut to those samples."""
    source = 50 if round(offset_s * 10) != offset_s * 10 else 10
    flown = _fly(scenario, sequence, k, rng, source, engine, 30.0)
    t = np.asarray(flown.time_s)
    keep = np.isclose(np.mod(t - offset_s + 0.5, 1.0), 0.5, atol=1e-6)
    omega = np.asarray(flown.omega_rad_s)
    return type(flown)(
        time_s=t[keep].tolist(), omega_rad_s=omega[keep].tolist(), sequence_start=0.0
    )


def run(grid_hz: float, step_s: float, gyros: tuple, args: Any, engine: str) -> dict:
    scenario = preset(
        "paper-in-orbit",
        timing={"step_duration_s": step_s, "integration_step_s": 0.01, "sample_rate_hz": grid_hz},
    )
    sequence = SEQUENCES[args.sequence]
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    n_train = kind_class(DEFAULT_KIND).DEFAULT_REALISATIONS
    model = train_classifier(scenario, sequence, n_train, rng)
    grid = scenario.sample_times(len(sequence))
    print(
        f"[{grid_hz:g} Hz grid, {step_s:g} s steps, {args.sequence} {sequence}] "
        f"{model.kind} trained on {len(grid)} grid times in "
        f"{time.perf_counter() - start:.1f} s; test telemetry by {engine}, "
        f"{args.n} series a candidate a rate"
    )
    rows, figures = [], {}
    window = max(30.0, DEFAULT_PRE_START_WINDOW_S)
    for rate, offset in gyros:
        counts = {"means": [0, 0, 0], "fit": [0, 0, 0]}
        total = 0
        for k in range(scenario.n_candidates):
            for _ in range(args.n):
                telemetry = (
                    _fly_off_grid(scenario, sequence, k, rng, offset, engine)
                    if offset
                    else _fly(scenario, sequence, k, rng, rate, engine, 30.0)
                )
                total += 1
                for name in counts:
                    patch = (
                        mock.patch.object(identify_module.ResponseShape, "of", _no_breaks)
                        if name == "means"
                        else contextlib.nullcontext()
                    )
                    with patch:
                        verdict = identify(model, telemetry, pre_start_window_s=window)
                    right = verdict.candidate_index == k
                    counts[name][0] += int(right)
                    counts[name][1] += int(verdict.status == "identified" and right)
                    counts[name][2] += int(verdict.status in FLAGGED)
        gyro = f"{rate} Hz" + (f", {offset:g} s off" if offset else "")
        for name, label in (("means", "no breaks (before)"), ("fit", "breaks known")):
            named, identified, flagged = counts[name]
            rows.append(
                [
                    gyro,
                    label,
                    _share(named, total),
                    _share(identified, total),
                    _share(flagged, total),
                ]
            )
            figures[f"{gyro}/{name}"] = {
                "series": total,
                "named": named,
                "identified": identified,
                "false_alarms": flagged,
            }
    print_table(
        ["gyro", "identify", "named right", "identified right at 0.99", "false alarms"], rows
    )
    return figures


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20, help="series per candidate per rate")
    parser.add_argument(
        "--grids", type=int_list, default=[1, 20], help="grid rates to run, of 1 and 20 Hz"
    )
    parser.add_argument("--sequence", choices=sorted(SEQUENCES), default="fire-brake")
    args = parser.parse_args()
    print_header("Telemetry faster than the classifier's grid", args)
    engine = "basilisk" if basilisk_available() else "native"
    if engine == "native":
        print("NOTE: Basilisk (bsk) does not import here: test telemetry from our native simulator")
    start = time.perf_counter()
    figures = {
        f"{grid:g}Hz": run(grid, step, rates, args, engine)
        for grid, step, rates in CONFIGURATIONS
        if int(grid) in args.grids
    }
    print(f"total {time.perf_counter() - start:.0f} s")
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
