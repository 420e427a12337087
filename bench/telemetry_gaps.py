"""Telemetry with a dropout: accuracy of the default classifier on passes with a hole
against the same passes without one.

The paper-in-orbit preset (initial rates and gyro biases drawn) flown with the paper's
hand-designed step ``[4, 4, 4, 0, 0, 0]`` repeated ``--steps`` times (12 s by default: a
5 s hole leaves more than half of it), the default classifier (marginal likelihood, its
default realisations) trained at 1x noise. Test series: ``--series`` per candidate
at ``--process`` times the process noise, sent at ``--rate`` Hz (every n-th sample of
the 20 Hz simulation), from the sequence start (no telemetry before it). Each series is
judged whole, and with each ``--holes`` length lost (every sample strictly inside the
hole), the hole starting at one of ``--hole-starts`` in turn; ``identify`` judges it on
the grid times its samples cover (the exact Gaussian marginal). With ``--head`` each
hole starts at the sequence start instead: a pass whose first ``--holes`` seconds were
lost (acquired late), judged the same way; with ``--tail`` each hole ends at the
sequence's end: a pass whose last ``--holes`` seconds were lost (it ended early).
With ``--loss`` every sample is also lost at random with that probability (packet loss,
drawn per series): the grid times measured then differ between nearby starts.

With ``--start-within W`` the start is searched: each series is flown with 30 s of quiet
before the sequence (the pre-start window the verdict conditions on) and ``W`` + 1 s
after, the stated start is off the true one by a whole number of grid periods drawn
within ``±W / 2``, and ``identify(..., estimate_start_within_s=W)`` judges it. The row
adds the part of the searches that found the true start, and of the others how many
took a start that measured fewer, more or the same number of grid times as the true
one, or could not try the true start (the telemetry falls short of it at an end: the
search tries only the starts the telemetry reaches at both ends, so ``--head`` and
``--tail`` do not combine with it). ``--loss`` and ``--start-within`` are for this
accuracy mode, not ``--coverage``. With ``--sub-grid`` the stated start is off the true
one by any amount within ``±W / 2``, not a whole number of grid periods, and the samples
lie at a random phase from the true start (the pass simulated at 100 Hz, read every
n-th sample from a random one of the first n): the true start then lies anywhere
between the grid times the search tries, as a spacecraft's clock leaves it. The row
adds how far the start taken lies from the true one, in grid periods (median, 90th
percentile and largest of its size), and the part of the searches that refined the
start below the grid. ``--rate`` above the grid's (100 Hz) simulates the pass at that
rate, the classifier's grid unchanged.

Per row: accuracy of the most probable candidate (with its 95 % Wilson interval), the
fraction "identified" at 0.99 and the errors among them, genuine series called matches
none (false alarms), and the mean part of the sequence covered.

With ``--coverage`` (fractions of the sequence's grid times left covered, e.g.
``0.75,0.5,0.35,0.25,0.15``) it measures calibration against coverage instead: the
sequence is ``--steps`` steps (4, the paper's ``[4, 4, 4, 0, 0, 0] x 4``), the telemetry
``--rate`` Hz (20, the grid's), and each series loses one hole that leaves that part of
the grid times covered, at a place drawn at random (fixed seed) strictly inside the
sequence, at each ``--process`` multiple. The floor
(:data:`~inertia_id.evaluation.telemetry.MIN_COVERED_FRACTION`) is lifted for the
measurement, so that the rows below it say what a verdict there would be worth; the
column "floor" says whether the shipped floor admits the row. Per row: the identified
rate at the default confidence (0.99), wrong among identified (with its 95 % Wilson
interval), genuine series called matches none, and accuracy of the most probable.

Run: python bench/telemetry_gaps.py [--series 20] [--holes 0.5,2,5] [--process 6] [--head | --tail]
     python bench/telemetry_gaps.py --steps 4 --rate 20 --loss 0.3 --holes 0.5 \
         --hole-starts 1,2 --start-within 0.3 --process 1
     python bench/telemetry_gaps.py --coverage 0.75,0.5,0.35,0.25,0.15 --process 1,6 \
         --steps 4 --rate 20 --series 20
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, float_list, print_header, print_table, write_json

from inertia_id.classifiers.registry import default_realisations, train_classifier
from inertia_id.cli.scenario import _at_rate
from inertia_id.evaluation import telemetry as telemetry_module
from inertia_id.evaluation.identify import identify
from inertia_id.evaluation.sweep import wilson_interval
from inertia_id.evaluation.telemetry import Telemetry, estimate_sequence_start
from inertia_id.physics.presets import preset
from inertia_id.physics.simulate import simulate


def _telemetry(
    t: np.ndarray,
    omega: np.ndarray,
    hole: tuple[float, float] | None,
    lost: np.ndarray | None = None,
    start_s: float | None = None,
) -> Telemetry:
    """The samples outside ``hole`` and not ``lost``; ``start_s`` the stated start (None:
    the stamps' 0)."""
    keep = np.ones(len(t), dtype=bool) if lost is None else ~lost
    if hole is not None:
        keep &= ~((t > hole[0] + 1e-9) & (t < hole[1] - 1e-9))
    return Telemetry(
        time_s=t[keep].tolist(), omega_rad_s=omega[keep].tolist(), sequence_start=start_s
    )


def _start_found(
    classifier: Any, verdict: Any, telemetry: Telemetry, stated: float, grid_period: float
) -> str:
    """Whether the start search found the true start (0 s, ``stated`` s before the stated
    one): "right", else whether the start it took measured "fewer", "more" or the "same"
    number of grid times as the true start, or the true start was "untried" (the
    telemetry does not reach it at an end)."""
    if abs(stated + verdict.sequence_start_shift_s) < grid_period / 2:
        return "right"
    grid = classifier.scenario_.sample_times(len(classifier.sequence_))
    tried: list[float] = []
    with contextlib.suppress(ValueError):
        # The search's own rule for which starts it tries, on the same shifts.
        estimate_sequence_start(
            telemetry,
            grid,
            lambda *_: 0.0,
            # The nearest grid start to a true start between grid times too (--sub-grid).
            window_s=abs(stated) + grid_period / 2,
            tried=tried,
            marginalise_gaps=True,
        )
    true_shift = [shift for shift in tried if abs(stated + shift) <= grid_period / 2]
    if not true_shift:
        return "untried"
    truth = identify(classifier, telemetry.shifted(true_shift[0]), start_hint=False)
    # The fractions are of the same grid's times: compare them as counts.
    measured = round(verdict.sequence_measured_fraction * classifier.length_)
    truly = round(truth.sequence_measured_fraction * classifier.length_)
    return "fewer" if measured < truly else "more" if measured > truly else "same"


@dataclass
class Tally:
    """Verdicts counted against the truth: right top candidate, identified, wrong among
    identified, matches none, and the part of the sequence each covered."""

    total: int = 0
    right: int = 0
    identified: int = 0
    wrong: int = 0
    flagged: int = 0
    covered: list[float] = field(default_factory=list)

    def add(self, verdict: Any, truth: int) -> None:
        self.total += 1
        self.right += verdict.candidate_index == truth
        named = verdict.status == "identified"
        self.identified += named
        self.wrong += named and verdict.candidate_index != truth
        self.flagged += verdict.matches_none
        self.covered.append(verdict.sequence_covered_fraction)


def _coverage(args: Any) -> None:
    """Calibration against the part of the sequence covered (``--coverage``)."""
    print_header("Telemetry with a hole: calibration against the part covered", args)
    rng = np.random.default_rng(args.seed)
    scenario = preset("paper-in-orbit")
    sequence = GOOD_SEQUENCE[:1] * args.steps
    realisations = args.realisations or default_realisations("marginal-likelihood")
    classifier: Any = train_classifier(scenario, sequence, realisations, rng)
    shipped_floor = telemetry_module.MIN_COVERED_FRACTION
    # Lifted for the measurement: the rows below the floor are the evidence for it.
    telemetry_module.MIN_COVERED_FRACTION = 0.0
    every = round(scenario.timing.sample_rate_hz / args.rate)
    rows, figures = [], {}
    for process in args.process:
        result = simulate(scenario, sequence, args.series, rng, process_noise_scale=process)
        t = np.asarray(result.time_s)[every - 1 :: every]
        omega = result.omega_measured[:, :, every - 1 :: every]
        grid_times = len(result.time_s)
        for fraction in [1.0, *args.coverage]:
            # A hole between two kept samples loses the samples strictly inside it, and
            # with them the grid times it leaves `fraction` of the sequence's.
            lost = round((1.0 - fraction) * grid_times)
            room = len(t) - (lost * len(t)) // grid_times - 2
            tally = Tally()
            for k in range(scenario.n_candidates):
                for i in range(args.series):
                    keep = np.ones(len(t), dtype=bool)
                    if lost:
                        first = int(rng.integers(0, room + 1))
                        keep[first + 1 : first + 1 + (lost * len(t)) // grid_times] = False
                    telemetry = Telemetry(
                        time_s=t[keep].tolist(), omega_rad_s=omega[k, i][keep].tolist()
                    )
                    tally.add(identify(classifier, telemetry), k)
            total, right, identified = tally.total, tally.right, tally.identified
            wrong, flagged = tally.wrong, tally.flagged
            low, high = wilson_interval(wrong, max(identified, 1))
            share = float(np.mean(tally.covered))
            # The mean of fractions that are each exactly the floor can fall a rounding
            # error below it (0.15 read 0.14999999999999997, labelled "refused").
            admitted = share >= shipped_floor - 1e-9
            figures[f"{process:g}x {fraction:g}"] = {
                "process_noise": process,
                "covered_fraction": share,
                "series": total,
                "identified": identified / total,
                "wrong_among_identified": wrong / max(identified, 1),
                "wrong_interval": [low, high],
                "matches_none": flagged / total,
                "accuracy": right / total,
                "admitted_by_floor": admitted,
            }
            rows.append(
                [
                    f"{process:g}x",
                    f"{100 * share:.1f} %",
                    total,
                    identified / total,
                    f"{wrong}/{identified}",
                    f"{low:.3f}-{high:.3f}",
                    flagged / total,
                    right / total,
                    "admitted" if admitted else "refused",
                ]
            )
    print_table(
        [
            "process",
            "covered",
            "series",
            "identified",
            "wrong|identified",
            "95% interval",
            "matches none",
            "accuracy",
            "floor",
        ],
        rows,
        title=f"{args.rate:g} Hz telemetry, {args.steps}-step sequence, one hole at a random "
        f"place, floor {shipped_floor:.0%} lifted for the measurement",
    )
    write_json(args.json, args, {"rows": figures})


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=12, help="steps of 1 s in the sequence")
    parser.add_argument("--series", type=int, default=20, help="test series per candidate")
    parser.add_argument("--process", type=float_list, default=[6.0], help="process noise multiples")
    parser.add_argument("--rate", type=float, default=10.0, help="telemetry rate, Hz")
    parser.add_argument("--holes", type=float_list, default=[0.5, 2.0, 5.0], help="hole lengths, s")
    parser.add_argument(
        "--hole-starts", type=float_list, default=[1.0, 3.5, 6.0], help="hole starts, s"
    )
    ends = parser.add_mutually_exclusive_group()
    ends.add_argument(
        "--head",
        action="store_true",
        help="lose each hole from the sequence start (a pass acquired late)",
    )
    ends.add_argument(
        "--tail",
        action="store_true",
        help="lose each hole up to the sequence's end (a pass that ended early)",
    )
    parser.add_argument(
        "--loss",
        type=float,
        default=0.0,
        help="probability that each sample is also lost at random (packet loss)",
    )
    parser.add_argument(
        "--start-within",
        type=float,
        default=None,
        metavar="W",
        help="search the start within ±W s, the stated one off by up to W/2 (see above)",
    )
    parser.add_argument(
        "--sub-grid",
        action="store_true",
        help="with --start-within: the true start anywhere between grid times (see above)",
    )
    parser.add_argument("--realisations", type=int, default=None, help="training realisations")
    parser.add_argument(
        "--coverage",
        type=float_list,
        default=None,
        help="measure calibration against these covered fractions instead (see above)",
    )
    args = parser.parse_args()
    if args.coverage is not None:
        _coverage(args)
        return
    if len(args.process) != 1:
        parser.error(f"--process takes one multiple without --coverage, got {args.process}")
    if not 0.0 <= args.loss < 1.0:
        parser.error(f"--loss must be a probability in [0, 1), got {args.loss:g}")
    if args.start_within is not None:
        if not (math.isfinite(args.start_within) and args.start_within > 0):
            parser.error(
                f"--start-within must be a number of seconds > 0, got {args.start_within:g}"
            )
        if args.head or args.tail:
            parser.error(
                "--start-within does not combine with --head or --tail: the start search "
                "tries only the starts the telemetry reaches at both ends"
            )
    if args.sub_grid and args.start_within is None:
        parser.error("--sub-grid is for the start search: give --start-within")
    process = args.process[0]
    print_header("Telemetry with a hole: accuracy against the same series whole", args)
    rng = np.random.default_rng(args.seed)
    scenario = preset("paper-in-orbit")
    sequence = GOOD_SEQUENCE[:1] * args.steps
    realisations = args.realisations or default_realisations("marginal-likelihood")
    started = time.perf_counter()
    classifier: Any = train_classifier(scenario, sequence, realisations, rng)
    print(
        f"trained {classifier.kind} on {realisations} realisations in "
        f"{time.perf_counter() - started:.1f} s",
        flush=True,
    )
    duration = float(len(sequence))  # steps of 1 s
    search = args.start_within
    before = after = 0
    if search is not None:
        # Quiet before (the pre-start window the verdict conditions on) and after, so that
        # the telemetry reaches every start searched; stamps in s from the true start.
        before, after = 30, math.ceil(search) + 1
    quiet = [[0] * scenario.n_thrusters]
    flown = quiet * before + sequence + quiet * after
    grid_rate = scenario.timing.sample_rate_hz
    # Faster than the grid, or at a random phase from the true start: simulated faster.
    sim_rate = max(args.rate, 5.0 * grid_rate if args.sub_grid else grid_rate)
    every = round(sim_rate / args.rate)
    if abs(every * args.rate - sim_rate) > 1e-9 * sim_rate:
        parser.error(f"--rate {args.rate:g} Hz does not divide the simulation's {sim_rate:g} Hz")
    flying = scenario if sim_rate == grid_rate else _at_rate(scenario, sim_rate)
    result = simulate(flying, flown, args.series, rng, process_noise_scale=process)
    times = np.asarray(result.time_s) - before
    grid_period = 1.0 / grid_rate
    cases: list[tuple[str, float | None]] = [("none", None), *((f"{h:g} s", h) for h in args.holes)]
    rows, figures = [], {}
    for name, length in cases:
        tally = Tally()
        refused = 0
        # Start search: found the true start; a wrong start that measured fewer or more
        # grid times than the true one (the raw distance's bias favoured fewer).
        starts = dict.fromkeys(("right", "fewer", "more", "same", "untried"), 0)
        errors: list[float] = []  # each search's start less the true one, s
        refined = 0
        started = time.perf_counter()
        for k in range(scenario.n_candidates):
            for i in range(args.series):
                hole = None
                if length is not None:
                    begin = args.hole_starts[(k * args.series + i) % len(args.hole_starts)]
                    if args.head:
                        hole = (0.0, length)
                    elif args.tail:
                        hole = (duration - length, math.inf)
                    else:
                        hole = (begin, begin + length)
                # The samples a pass reads: every n-th, from the last of the first n (the
                # grid's times at the grid's rate) or, with --sub-grid, a random one.
                first = int(rng.integers(0, every)) if args.sub_grid else every - 1
                t, omega = times[first::every], result.omega_measured[k, i, first::every]
                lost = rng.random(len(t)) < args.loss if args.loss > 0 else None
                stated = None
                if search is not None and args.sub_grid:
                    stated = float(rng.uniform(-search / 2, search / 2))
                elif search is not None:
                    off = math.floor(search / 2 / grid_period + 1e-9)
                    stated = float(rng.integers(-off, off + 1)) * grid_period
                telemetry = _telemetry(t, omega, hole, lost, stated)
                try:
                    verdict = identify(classifier, telemetry, estimate_start_within_s=search)
                except ValueError as exc:
                    refused += 1
                    print(f"  refused ({name}): {exc}")
                    continue
                tally.add(verdict, k)
                if stated is not None:
                    found = _start_found(classifier, verdict, telemetry, stated, grid_period)
                    starts[found] += 1
                    errors.append(round(stated + verdict.sequence_start_shift_s, 6))
                    refined += bool(getattr(verdict, "sequence_start_refined", False))
        right, identified, wrong, flagged = (
            tally.right,
            tally.identified,
            tally.wrong,
            tally.flagged,
        )
        covered = tally.covered
        total = scenario.n_candidates * args.series
        low, high = wilson_interval(right, total)
        seconds = time.perf_counter() - started
        figures[name] = {
            "series": total,
            "accuracy": right / total,
            "accuracy_interval": [low, high],
            "identified": identified / total,
            "errors_among_identified": wrong / max(identified, 1),
            "false_alarms": flagged / total,
            "refused": refused,
            "mean_covered_fraction": float(np.mean(covered)) if covered else None,
            "seconds": seconds,
        }
        row = [
            name,
            total,
            right / total,
            f"{low:.3f}-{high:.3f}",
            identified / total,
            wrong / max(identified, 1),
            flagged / total,
            refused,
            float(np.mean(covered)) if covered else None,
        ]
        if search is not None:
            figures[name]["right_start"] = starts["right"] / total
            figures[name]["wrong_starts"] = {k: v for k, v in starts.items() if k != "right"}
            figures[name]["start_errors_s"] = errors
            size = np.abs(errors) / grid_period if errors else np.array([np.nan])
            spread = [float(np.median(size)), float(np.quantile(size, 0.9)), float(size.max())]
            figures[name]["start_error_periods"] = dict(
                zip(("median", "p90", "max"), spread, strict=True)
            )
            figures[name]["refined"] = refined / total
            row += [
                starts["right"] / total,
                "/".join(str(starts[k]) for k in ("fewer", "more", "same", "untried")),
                "/".join(f"{v:.2f}" for v in spread),
                refined / total,
            ]
        rows.append([*row, seconds])
    header = [
        "hole",
        "series",
        "accuracy",
        "95% interval",
        "identified",
        "wrong|identified",
        "false alarms",
        "refused",
        "covered",
    ]
    if search is not None:
        header += [
            "right start",
            "wrong: fewer/more/same measured/true untried",
            "|start error|, periods: median/p90/max",
            "refined",
        ]
    where = ""
    if args.head:
        where = ", each hole from the sequence start"
    elif args.tail:
        where = ", each hole up to the sequence's end"
    if args.loss:
        where += f", {args.loss:.0%} of samples lost at random"
    if search is not None:
        where += f", start searched within ±{search:g} s"
        if args.sub_grid:
            where += ", true start between grid times"
    print_table(
        [*header, "s"],
        rows,
        title=f"{args.rate:g} Hz telemetry, {process:g}x process noise, {args.steps}-step sequence"
        + where,
    )
    write_json(args.json, args, {"rows": figures})


if __name__ == "__main__":
    main()
