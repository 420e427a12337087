"""The start search on telemetry with nothing before the start and its first sample late:
how often it finds the right start.

README's telemetry (``simulate --telemetry``) begins at the sequence start. Here each
series is that telemetry with every stamp ``--late`` seconds later, the start stated at
0: the true start lies ``--late`` s after the stated one, which the telemetry does not
reach (its first sample is late), so the search tries only the starts its edge rule
lets it (a period or two wide when the telemetry ends with the sequence; with
``--after`` seconds of quiet flown after the sequence, every later start within the
window). The ``--preset`` scenario's default classifier (marginal likelihood,
``--realisations`` per candidate, trained at 1x) judges ``--series`` fresh series per
candidate at ``--process`` times the process noise with
``identify(..., estimate_start_within_s=--within)``, one row per ``--late``.

With ``--early`` the rows are telemetry that reaches the stated start, its first sample a
period after it as README's: the true start that many seconds after the stated one (0: the
stated start right, README's telemetry itself), the body flown
quiet for a step before the sequence so that the samples between the stated start and
the true one are the body's drift (the series simulated after the ``--late`` ones).

Per row: the part of the searches that took the right start (within half a grid period
of the true one), the start errors taken (in grid periods, and how many each), the
accuracy of the most probable candidate, the right candidate identified at 0.99, and how
many verdicts of each status.

Run: python bench/late_start_search.py [--late 0.05,0.25] [--early 0,0.05] [--series 20]
[--after 0] [--preset paper-in-orbit]
"""

from __future__ import annotations

import argparse
import collections
import math
import time
from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, begin, float_list, print_table, write_json

from inertia_id.classifiers.registry import default_realisations, train_classifier
from inertia_id.evaluation.identify import identify
from inertia_id.evaluation.telemetry import Telemetry
from inertia_id.physics.presets import preset
from inertia_id.physics.simulate import simulate


def seconds_list(text: str) -> list[float]:
    """argparse type: a comma-separated list of seconds >= 0 (0 is a row)."""
    try:
        values = [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected seconds separated by commas, got {text!r}"
        ) from None
    if not values or not all(math.isfinite(v) and v >= 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected seconds >= 0, got {text!r}")
    return values


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--preset", default="paper", help="scenario preset")
    parser.add_argument(
        "--late", type=float_list, default=[0.05, 0.25], help="first sample this late, s"
    )
    parser.add_argument(
        "--early",
        type=seconds_list,
        default=[],
        help="rows whose stated start is the first sample, the true start this much later, s",
    )
    parser.add_argument("--series", type=int, default=20, help="test series per candidate")
    parser.add_argument("--process", type=float, default=1.0, help="process noise multiple")
    parser.add_argument("--within", type=float, default=0.5, help="start search window, ± s")
    parser.add_argument("--after", type=int, default=0, help="seconds of quiet after")
    parser.add_argument("--realisations", type=int, default=None, help="training realisations")
    args = begin(parser, "Start search with nothing before the start, first sample late")
    rng = np.random.default_rng(args.seed)
    scenario = preset(args.preset)
    realisations = args.realisations or default_realisations("marginal-likelihood")
    started = time.perf_counter()
    classifier: Any = train_classifier(scenario, GOOD_SEQUENCE, realisations, rng)
    print(f"trained on {realisations} realisations in {time.perf_counter() - started:.1f} s")
    quiet = [[0] * scenario.n_thrusters]
    period = 1.0 / scenario.timing.sample_rate_hz
    step = scenario.timing.step_duration_s
    if any(e > step for e in args.early):
        parser.error(f"--early beyond the quiet step flown before the sequence ({step:g} s)")
    flown = GOOD_SEQUENCE + quiet * args.after
    result = simulate(scenario, flown, args.series, rng, process_noise_scale=args.process)
    cases: list[tuple[str, float, np.ndarray, np.ndarray, float]] = [
        (f"late {late:g} s", late, np.asarray(result.time_s) + late, result.omega_measured, 0.0)
        for late in args.late
    ]
    if args.early:
        lead = simulate(scenario, quiet + flown, args.series, rng, process_noise_scale=args.process)
        # The true start at 0: the quiet step flown first lies before it.
        lead_time = np.asarray(lead.time_s) - step
        for early in args.early:
            # As README's telemetry: the first sample a period after the stated start.
            kept = lead_time > -early + 1e-9 * step
            cases.append(
                (
                    f"early {early:g} s",
                    early,
                    lead_time[kept],
                    lead.omega_measured[:, :, kept],
                    -early,
                )
            )
    rows, figures = [], {}
    for name, true_shift, stamps, omega, stated in cases:
        right = accurate = identified = 0
        errors: collections.Counter[int] = collections.Counter()
        statuses: collections.Counter[str] = collections.Counter()
        tried: list[int] = []
        for k in range(scenario.n_candidates):
            for i in range(args.series):
                telemetry = Telemetry(
                    time_s=stamps.tolist(),
                    omega_rad_s=omega[k, i].tolist(),
                    sequence_start=stated,
                )
                verdict = identify(classifier, telemetry, estimate_start_within_s=args.within)
                error = (verdict.sequence_start_shift_s - true_shift) / period
                errors[round(error)] += 1
                statuses[verdict.status] += 1
                right += abs(error) < 0.5
                accurate += verdict.candidate_index == k
                identified += verdict.status == "identified" and verdict.candidate_index == k
                low, high = verdict.sequence_start_shifts_tried_s or [0.0, 0.0]
                tried.append(round((high - low) / period) + 1)
        total = scenario.n_candidates * args.series
        spread = ", ".join(f"{e:+d}: {n}" for e, n in sorted(errors.items()))
        figures[name] = {
            "series": total,
            "right_start": right / total,
            "start_errors_periods": {str(e): n for e, n in sorted(errors.items())},
            "accuracy": accurate / total,
            "identified_right": identified / total,
            "verdicts": dict(sorted(statuses.items())),
            "starts_tried_mean": float(np.mean(tried)),
        }
        rows.append(
            [
                name,
                total,
                f"{np.mean(tried):.1f}",
                right / total,
                spread,
                accurate / total,
                identified / total,
                ", ".join(f"{s}: {n}" for s, n in sorted(statuses.items())),
            ]
        )
    print_table(
        [
            "telemetry",
            "series",
            "starts tried",
            "right start",
            "start error (periods): count",
            "accuracy",
            "identified right",
            "verdicts",
        ],
        rows,
        title=f"{args.preset}, {args.process:g}x process noise, search ±{args.within:g} s, "
        f"{args.after} s after the sequence",
    )
    write_json(args.json, args, {"rows": figures})


if __name__ == "__main__":
    main()
