"""The hand-designed sequences scored on the very draws a search's best sequence was.

What a search adds over a hand-designed excitation (:mod:`inertia_id.physics.sequences`)
is only visible on the same fresh noise draws: :func:`compare_with_baselines` scores each
baseline there.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..physics.scenario import Scenario
from ..physics.sequences import baseline_sequences
from .records import evaluate_sequence
from .scorer import ScorerSettings

__all__ = ["STOPPED", "compare_with_baselines"]

#: Why a baseline was not scored once ``should_stop`` said so.
STOPPED = "not scored: the search was cancelled"


def compare_with_baselines(
    scenario: Scenario,
    sequence_length: int,
    settings: ScorerSettings,
    *,
    seed: int,
    n_draws: int = 5,
    should_stop: Callable[[], bool] | None = None,
) -> dict[str, dict[str, Any]]:
    """Each baseline of ``sequence_length`` steps scored on given fresh draws.

    Pass a search result's ``fresh.seed`` and its number of draws: the baselines are then
    scored on exactly the draws the search's best sequence was, so the comparison is
    paired.

    :param settings: the search's :class:`~inertia_id.search.ScorerSettings`.
    :param should_stop: asked before each baseline and each prefix it clusters
        (:func:`~inertia_id.search.records.evaluate_sequence`); once True the rest, and
        the one under way, are ``unavailable`` ("not scored: the search was cancelled").
        A cancelled search scored every baseline on its fresh draws first, minutes on a
        large scenario.
    :returns: by baseline name: the sequence, the clustering F1 and mean final rate
        (rad/s) on each draw, and the fuel (commanded impulse, N m s); for a baseline the
        length or the thruster geometry does not allow, ``unavailable`` (why), as for an
        axis-in-turn that the geometry makes the hand-designed sequence itself (it is
        not scored twice; :func:`~inertia_id.physics.sequences.baseline_sequences`).
    """
    out: dict[str, dict[str, Any]] = {}
    for name, sequence in baseline_sequences(scenario, sequence_length).items():
        if isinstance(sequence, str):
            out[name] = {"unavailable": sequence}
            continue
        if should_stop is not None and should_stop():
            out[name] = {"unavailable": STOPPED}
            continue
        fresh = evaluate_sequence(
            scenario, sequence, settings, seed=seed, n_draws=n_draws, should_stop=should_stop
        )
        if len(fresh.f1) < n_draws:  # stopped under way: on the best's draws, or not at all
            out[name] = {"unavailable": STOPPED}
            continue
        out[name] = {
            "sequence": sequence.tolist(),
            "fresh_f1": list(fresh.f1),
            "fresh_final_rate_rad_s": list(fresh.final_rate_rad_s),
            "fuel_nms": scenario.impulse_nms(sequence),
        }
    return out
