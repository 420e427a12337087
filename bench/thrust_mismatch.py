"""Thrusters weaker than the scenario says: does the verdict stay honest?

Torque and inertia enter the dynamics as their ratio, so a thrust shortfall the scenario
does not state looks like a heavier body. Data: the paper preset and the hand-designed
sequence; the default classifier (marginal likelihood, 100 realisations per candidate)
trained on the scenario as stated, then --series telemetry series per candidate flown
with the torque of every thruster ("all") or of one (numbered from 1) of --thrusters
scaled by each of --scales (the same seed for every scale), each judged by ``identify``:
identified right, identified wrong (at the required confidence, 0.99; of which: the
verdict notes that its classifier cannot test for other bodies, ``off_candidates_note``),
ambiguous (of which: a candidate reached 0.99 but the telemetry fit another body better,
``fits_off_candidates``), or matches none / not this sequence. Twice: trained with the
preset's thrust-scale sigma (0, thrust known exactly), and with the scenario stating
--stated-sigma per thruster. Scale 1 is the nominal telemetry: its "right" column is
the accuracy at 0.99, the rest false alarms.

With --online the same series are also decided by ``identify_online`` (alpha 1e-3):
decided right, decided wrong, of those wrong the ones whose data by the end fit another
body better (``fits_off_candidates``: flagged) or that note the test was not made,
undecided, and the median decision time of the right decisions.

--kind judges with another kind: ``likelihood`` has no model of other bodies, so its
verdicts carry ``off_candidates_note`` instead of the flag.

Run: python bench/thrust_mismatch.py [--series 40] [--scales 1,0.95,0.9] [--thrusters all,1]
[--online] [--exact-only] [--kind likelihood]
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, begin, float_list, print_table, write_json

from inertia_id import Scenario, simulate, train_classifier
from inertia_id.evaluation.identify import identify, identify_online
from inertia_id.evaluation.telemetry import Telemetry


def weaker(scenario: Scenario, scale: float, thruster: int | None = None) -> Scenario:
    """``scenario`` with every thruster's torque (``thruster`` None) or one's (its column,
    from 0) scaled by ``scale``."""
    document = scenario.model_dump()
    matrix = np.asarray(document["thrusters"]["torque_matrix_nm"])
    if thruster is None:
        matrix = matrix * scale
    else:
        matrix[:, thruster] *= scale
    document["thrusters"]["torque_matrix_nm"] = matrix.tolist()
    return Scenario.model_validate(document)


def thruster_list(text: str) -> list[int | None]:
    """argparse type: 'all' (every thruster at once) or thruster numbers from 1, by commas."""
    chosen: list[int | None] = []
    for part in (p.strip() for p in text.split(",") if p.strip()):
        if part == "all":
            chosen.append(None)
        elif part.isdigit() and int(part) >= 1:
            chosen.append(int(part) - 1)
        else:
            raise argparse.ArgumentTypeError(
                f"expected 'all' or thruster numbers from 1, got {part!r}"
            )
    if not chosen:
        raise argparse.ArgumentTypeError(f"expected 'all' or thruster numbers, got {text!r}")
    return chosen


def online_decisions(model: Any, telemetry: Telemetry, k: int, counts: dict[str, Any]) -> None:
    """Count ``identify_online``'s decision on one series of candidate ``k``."""
    online = identify_online(model, telemetry)
    if not online.decided:
        counts["online_undecided"] += 1
    elif online.candidate_index == k:
        counts["online_right"] += 1
        counts["online_right_times_s"].append(online.decision_time_s)
    else:
        counts["online_wrong"] += 1
        # Absent from the online result before the rule reached it.
        counts["online_wrong_flagged"] += bool(getattr(online, "fits_off_candidates", 0))
        # A kind that cannot test for other bodies says so instead (absent before).
        counts["online_wrong_noted"] += bool(getattr(online, "off_candidates_note", None))


def verdicts(
    model: Any, flown: Scenario, series: int, seed: int, *, online: bool = False
) -> dict[str, Any]:
    result = simulate(flown, GOOD_SEQUENCE, series, np.random.default_rng(seed))
    times = flown.sample_times(len(GOOD_SEQUENCE)).tolist()
    counts: dict[str, Any] = {
        "right": 0,
        "wrong": 0,
        "ambiguous": 0,
        "fits_off_candidates": 0,
        "none": 0,
        "online_right": 0,
        "online_wrong": 0,
        "online_wrong_flagged": 0,
        "online_wrong_noted": 0,
        "wrong_noted": 0,
        "online_undecided": 0,
        "online_right_times_s": [],
    }
    wrong_confidence: list[float] = []
    for k in range(flown.n_candidates):
        for i in range(series):
            telemetry = Telemetry(time_s=times, omega_rad_s=result.omega_measured[k, i].tolist())
            verdict = identify(model, telemetry)
            if online:
                online_decisions(model, telemetry, k, counts)
            if verdict.status == "identified":
                right = verdict.candidate_index == k
                counts["right" if right else "wrong"] += 1
                if not right:
                    wrong_confidence.append(float(verdict.confidence))
                    counts["wrong_noted"] += bool(getattr(verdict, "off_candidates_note", None))
            elif verdict.status == "ambiguous":
                counts["ambiguous"] += 1
                # Absent from the verdict before the rule existed.
                counts["fits_off_candidates"] += bool(getattr(verdict, "fits_off_candidates", 0))
            else:
                counts["none"] += 1
    right_times = counts.pop("online_right_times_s")
    return {
        **counts,
        "wrong_confidence_min": min(wrong_confidence, default=None),
        "online_right_time_median_s": float(np.median(right_times)) if right_times else None,
    }


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=40, help="telemetry series per candidate")
    parser.add_argument("--scales", type=float_list, default=[1.0, 0.95, 0.9])
    parser.add_argument(
        "--thrusters",
        type=thruster_list,
        default=[None],
        help="whose torque is scaled: 'all' at once, or thruster numbers from 1",
    )
    parser.add_argument("--stated-sigma", type=float, default=0.05, help="thrust_scale_sigma")
    parser.add_argument(
        "--online", action="store_true", help="also decide every series with identify_online"
    )
    parser.add_argument(
        "--kind",
        default=None,
        help="classifier kind (default: the default kind, marginal-likelihood)",
    )
    parser.add_argument(
        "--exact-only",
        action="store_true",
        help="only the classifier trained with the thrust known exactly (not --stated-sigma)",
    )
    args = begin(parser, "A thrust shortfall the scenario does or does not state")
    paper = Scenario.paper()
    document = paper.model_dump()
    document["uncertainty"]["thrust_scale_sigma"] = args.stated_sigma
    trained_on = {"thrust exact (preset)": paper, "stated": Scenario.model_validate(document)}
    if args.exact_only:
        del trained_on["stated"]
    rows, figures = [], {}
    for label, scenario in trained_on.items():
        model = train_classifier(
            scenario, GOOD_SEQUENCE, 100, np.random.default_rng(args.seed), kind=args.kind
        )
        sigma = scenario.uncertainty.thrust_scale_sigma
        for thruster in args.thrusters:
            which = "all" if thruster is None else f"thruster {thruster + 1}"
            for scale in args.scales:
                if scale == 1.0 and thruster is not None:
                    continue  # the nominal telemetry, once
                flown = weaker(paper, scale, thruster)
                found = verdicts(model, flown, args.series, args.seed + 7, online=args.online)
                torque = "nominal" if scale == 1.0 else f"{which} x{scale:g}"
                figures[f"{label} {torque}"] = found
                low = found["wrong_confidence_min"]
                row = [
                    f"{label}, sigma {sigma:g}",
                    torque,
                    found["right"],
                    found["wrong"],
                    "-" if low is None else f"{low:.4f}",
                    found["wrong_noted"],
                    found["ambiguous"],
                    found["fits_off_candidates"],
                    found["none"],
                ]
                if args.online:
                    median = found["online_right_time_median_s"]
                    row += [
                        found["online_right"],
                        found["online_wrong"],
                        found["online_wrong_flagged"],
                        found["online_wrong_noted"],
                        found["online_undecided"],
                        "-" if median is None else f"{median:.2f}",
                    ]
                rows.append(row)
    total = args.series * paper.n_candidates
    headers = [
        "trained on",
        "torque flown",
        "right",
        "wrong",
        "wrong, least conf.",
        "of which noted untested",
        "ambiguous",
        "of which fits off",
        "none",
    ]
    if args.online:
        headers += [
            "online right",
            "online wrong",
            "of which flagged",
            "of which noted untested",
            "undecided",
            "t50 right, s",
        ]
    print_table(
        headers,
        rows,
        title=(
            f"{total} series per row, {args.kind or 'default'} classifier, hand-designed sequence"
        ),
    )
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
