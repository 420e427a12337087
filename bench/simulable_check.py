"""Cost of the check that a scenario can be simulated at the noise a job asks for.

:func:`inertia_id.physics.simulable.check_simulable` flies seeded realisations of one
sequence with the jobs' simulator and refuses rates that overflow: as many a candidate as
its work budget allows (:func:`~inertia_id.physics.simulable.check_realisations`, 8 to
256; printed beside each figure). Every submission (a scenario, a
train, sweep or search job, a plan's flights, a response) runs it, so it must cost
milliseconds. Prints, on the paper preset, best-of-``--repeats`` wall times of:

- the check passing (the preset's own noise) at each ``--lengths`` of the hand-designed
  sequence: the whole sequence is flown;
- ``check_scenario_simulable`` (what storing a scenario runs: 4 steps);
- the check refusing 1e4 N m of disturbance (it stops at the first step that overflows,
  then flies each noise figure alone to name the one to blame);
- a sweep's check (1x, then each driving source at the largest of 1..8) and a search's
  (1x, then the design noise's 6x process).

numba is warmed up first, so compilation is not timed.
``python bench/simulable_check.py [--lengths 4,8,64] [--repeats 7]``
"""

from __future__ import annotations

from typing import Any

from _common import base_parser, begin, best_of, int_list, write_json

from inertia_id import Scenario
from inertia_id.evaluation.sweep import check_sweep_simulable
from inertia_id.physics.sequences import hand_designed
from inertia_id.physics.simulable import (
    NoiseOverflow,
    check_realisations,
    check_scenario_simulable,
    check_simulable,
)
from inertia_id.pipelines import check_search_scenario


def _refused(scenario: Scenario, sequence: Any) -> None:
    try:
        check_simulable(scenario, sequence)
    except NoiseOverflow:
        return
    raise AssertionError("the check did not refuse 1e4 N m")


def main() -> None:
    parser = base_parser(__doc__ or "")
    parser.add_argument("--lengths", type=int_list, default=[4, 8, 64], help="steps")
    parser.add_argument("--repeats", type=int, default=7, help="best of this many")
    args = begin(parser, "simulable check: cost on the paper preset")
    paper = Scenario.paper()
    overflowing = paper.with_uncertainty(disturbance_torque_sigma_nm=1e4)
    check_simulable(paper, hand_designed(paper, 2))  # numba's warm-up
    figures: dict[str, float] = {}
    realisations: dict[str, int] = {}
    cases: list[tuple[str, int, Any]] = []
    for length in args.lengths:
        sequence = hand_designed(paper, length)
        cases.append(
            (
                f"passes, {length} steps",
                length,
                lambda s=sequence: check_simulable(paper, s),
            ),
        )
    four = hand_designed(paper, 4)
    cases += [
        ("check_scenario_simulable (4 steps)", 4, lambda: check_scenario_simulable(paper)),
        ("refuses 1e4 N m, 4 steps", 4, lambda: _refused(overflowing, four)),
        (
            "sweep: 1x + process, jitter at 8x (4 steps)",
            4,
            lambda: check_sweep_simulable(
                paper, four, ("process", "measurement", "jitter"), range(1, 9)
            ),
        ),
        (
            "search: 1x + design noise 6x (4 steps)",
            4,
            lambda: check_search_scenario(paper, 4, None, ((6.0, 1.0), (1.0, 6.0))),
        ),
    ]
    for label, length, run in cases:
        best, _all, _ = best_of(run, args.repeats)
        figures[label] = best
        realisations[label] = check_realisations(paper, length)
        print(
            f"{label:45s} {best * 1e3:8.2f} ms (best of {args.repeats}; "
            f"{realisations[label]} realisations a candidate a flight)",
            flush=True,
        )
    write_json(args.json, args, {"seconds": figures, "realisations": realisations})


if __name__ == "__main__":
    main()
