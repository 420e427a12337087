"""The baselines on thruster geometries unlike the paper's: a brake weaker than the fire,
a tetrahedral set, and a geometry that leaves axis-in-turn nothing but hand-designed."""

from __future__ import annotations

import numpy as np
import pytest

from inertia_id import Scenario, preset, simulate
from inertia_id.physics.presets import NOISE_OFF
from inertia_id.physics.sequences import (
    BASELINES,
    axis_in_turn,
    baseline_sequences,
    fire_and_brake,
    hand_designed,
    principal_axes,
)
from inertia_id.search import ScorerSettings
from inertia_id.search.baselines import compare_with_baselines

SAME_AS_HAND = "the same sequence as hand-designed on this geometry"


def _with_torques(columns: list[list[float]] | np.ndarray) -> Scenario:
    """The paper preset (5 duty levels) with these thruster torques (one per column)."""
    matrix = np.asarray(columns, dtype=float).T
    return preset("paper", thrusters={"torque_matrix_nm": matrix.tolist(), "n_levels": 5})


def _net_impulse_nms(scenario: Scenario, sequence: np.ndarray) -> np.ndarray:
    torques = scenario.torque_matrix @ scenario.level_values[sequence].T  # (3, L)
    return torques.sum(axis=1) * scenario.timing.step_duration_s


def test_a_brake_weaker_than_the_fire_scales_the_fire_down_and_ends_at_rest() -> None:
    # +x, +y, +z at 2 N m; the only brake along -(1, 1, 1) at 1.5 N m per axis: a full
    # fire needs 4/3 of the brake's full duty. Before, the brake was clipped to full duty
    # and the fire kept at full: (1, 1, 1) N m s left over, 1.46 deg/s at the end.
    weak = _with_torques([[2, 0, 0], [0, 2, 0], [0, 0, 2], [-1.5, -1.5, -1.5]])
    fire, brake = fire_and_brake(weak)
    assert fire.tolist() == [3, 3, 3, 0] and brake.tolist() == [0, 0, 0, 4]
    assert hand_designed(weak, 1).tolist() == [[4, 4, 4, 0]]  # hand-designed stays full
    assert BASELINES["fire-then-brake"](weak, 4).tolist() == [[3, 3, 3, 0]] * 2 + [[0, 0, 0, 4]] * 2
    quiet = weak.with_uncertainty(**NOISE_OFF)
    for name, length in (("fire-then-brake", 4), ("fire-coast-brake", 4), ("fire-coast-brake", 8)):
        sequence = BASELINES[name](weak, length)
        assert np.allclose(_net_impulse_nms(weak, sequence), 0.0, atol=1e-12), name
        result = simulate(quiet, sequence, 1, np.random.default_rng(0))
        settled_deg_s = np.degrees(result.settled_rate_rad_s(quiet)).max()
        # Only the gyroscopic coupling between fire and brake is left (the paper
        # preset's own fire-then-brake at L = 4 settles at 0.16 deg/s).
        assert settled_deg_s < 0.5, (name, length, settled_deg_s)


def test_the_fire_is_the_one_the_brake_cancels_best_when_none_cancels_exactly() -> None:
    # A brake of 1.667 N m per axis: no fire level is cancelled exactly; 3/4 duty braked
    # at full leaves the least (11 % of the fired torque, against 17 % at full duty).
    scenario = _with_torques([[2, 0, 0], [0, 2, 0], [0, 0, 2], [-1.667, -1.667, -1.667]])
    fire, brake = fire_and_brake(scenario)
    assert fire.tolist() == [3, 3, 3, 0] and brake.tolist() == [0, 0, 0, 4]
    # With on/off thrusters there is nothing to scale: the fire stays full.
    on_off = preset(
        "paper",
        thrusters={"torque_matrix_nm": scenario.torque_matrix.tolist(), "n_levels": 2},
    )
    fire, brake = fire_and_brake(on_off)
    assert fire.tolist() == [1, 1, 1, 0] and brake.tolist() == [0, 0, 0, 1]


def test_the_paper_fire_and_brake_is_full_duty(paper: Scenario) -> None:
    fire, brake = fire_and_brake(paper)
    assert fire.tolist() == [4, 4, 4, 0, 0, 0] and brake.tolist() == [0, 0, 0, 4, 4, 4]


def _tetrahedral() -> Scenario:
    # Four thrusters along (1, 1, 1) and the three directions with two minus signs,
    # 2 N m each: every pair 109.5 degrees apart, thruster 1 plus another a pure axis.
    directions = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3)
    return _with_torques(2.0 * directions)


def test_a_tetrahedral_set_drives_each_axis_with_a_pair() -> None:
    tetra = _tetrahedral()
    torque = tetra.torque_matrix
    hand, turn = hand_designed(tetra, 3), axis_in_turn(tetra, 3)
    # Before, every pair counted as opposed (more than 90 degrees apart): axis-in-turn
    # fired thruster 1 alone every step, the hand-designed sequence itself.
    assert hand.tolist() == [[4, 0, 0, 0]] * 3
    assert turn.tolist() == [[4, 4, 0, 0], [4, 0, 4, 0], [4, 0, 0, 4]]
    assert BASELINES["axis-in-turn"](tetra, 3).tolist() == turn.tolist()
    axes = principal_axes(tetra)
    for step in range(3):
        applied = torque @ tetra.level_values[turn[step]]
        assert axes[step] @ applied / np.linalg.norm(applied) == pytest.approx(1.0)
        # Each thruster fired enlarges the step's torque: without it, it would be smaller.
        for j in np.flatnonzero(turn[step]):
            assert np.linalg.norm(applied - torque[:, j]) < np.linalg.norm(applied)
    # The brake is the other three at full duty: exactly -(thruster 1).
    sequence = BASELINES["fire-then-brake"](tetra, 4)
    assert sequence.tolist() == [[4, 0, 0, 0]] * 2 + [[0, 4, 4, 4]] * 2
    assert np.allclose(_net_impulse_nms(tetra, sequence), 0.0, atol=1e-12)


def test_thrusters_that_cannot_reverse_the_fire_have_no_fire_then_brake() -> None:
    """Three thrusters on one side of the body all torque +z: nothing brakes a fire.
    fire-then-brake was [[3, 3, 0]] * 2 + [[0, 0, 1]] * 2 all the same, its "brake" (the
    third thruster at a quarter duty) adding z torque and leaving 95 % of the fired
    torque; now both braking baselines are unavailable, saying why, and the others stay."""
    one_side = _with_torques([[1, 0, 0.5], [-0.5, 0.87, 0.5], [-0.5, -0.87, 0.5]])
    made = baseline_sequences(one_side, 4)
    for name in ("fire-then-brake", "fire-coast-brake"):
        why = made[name]
        assert isinstance(why, str), (name, why)
        assert "cannot reverse the fired torque [0.5, 0.87, 1.0] N m" in why, why
        assert "along body +z" in why and "no brake" in why, why
    assert made["hand-designed"].tolist() == [[4, 4, 0]] * 4  # type: ignore[union-attr]
    assert made["axis-in-turn"].tolist() == [  # type: ignore[union-attr]
        [4, 0, 0],
        [0, 4, 0],
        [4, 4, 4],
        [4, 0, 0],
    ]
    # A geometry that reverses the fire about no body axis is told so by a direction.
    skewed = _with_torques([[1, 0, 0.5], [-0.5, 0.87, 0.5], [-0.5, -0.87, 0.2], [0.1, 0.1, -0.01]])
    with pytest.raises(ValueError, match=r"component of 0 or more along \[0\.\d+, -0\.\d+"):
        BASELINES["fire-then-brake"](skewed, 2)
    # Where the opposite of the fire lies among the thrusters' torques, a brake is found:
    # a weaker one scales the fire down (above), a stronger one brakes it exactly.
    reversible = _with_torques([[1, 0, 0.5], [-0.5, 0.87, 0.5], [-0.5, -0.87, 0.5], [0, 0, -1]])
    sequence = BASELINES["fire-then-brake"](reversible, 2)
    assert np.allclose(_net_impulse_nms(reversible, sequence), 0.0, atol=1e-12)


def test_thrusters_that_cancel_are_never_fired_together(paper: Scenario) -> None:
    # On the paper's +-x, +-y, +-z the sets are those without an opposed pair, as before:
    # +x with -x adds nothing along their resultant, even beside +y.
    turn = axis_in_turn(paper, 3)
    assert turn.tolist() == [
        [4, 0, 0, 0, 0, 0],
        [0, 4, 0, 0, 0, 0],
        [0, 0, 4, 0, 0, 0],
    ]
    # A thruster nearly opposite a stronger one cancels more than it adds: never fired
    # with it, nor beside a third that tilts their sum (each would pass a test of a
    # positive component along the sum).
    lopsided = _with_torques([[2, 0, 0], [-1.9, 0.3, 0], [0, 2, 0], [0, 0, 2], [-1, -1, -1]])
    for row in axis_in_turn(lopsided, 3):
        assert not (row[0] and row[1])
    # Two slightly misaligned opposite thrusters sum to a sliver of torque exactly along
    # y, better aligned than the canted y thruster; they are still not fired for y.
    misaligned = _with_torques(
        [[2, 0.02, 0], [-2, 0.02, 0], [0.05, 2, 0.05], [0, 0, 2], [0, -2, 0], [0, 0, -2]]
    )
    assert axis_in_turn(misaligned, 3).tolist() == [
        [4, 0, 0, 0, 0, 0],
        [0, 0, 4, 0, 0, 0],
        [0, 0, 0, 4, 0, 0],
    ]


def test_an_axis_in_turn_that_is_hand_designed_is_unavailable_not_scored_twice() -> None:
    # One thruster along the diagonal and one against it: every axis's best set is the
    # first thruster alone, as is the hand-designed step.
    scenario = _with_torques([[1, 1, 1], [-1, -1, -1]])
    assert np.array_equal(axis_in_turn(scenario, 3), hand_designed(scenario, 3))
    with pytest.raises(ValueError, match=SAME_AS_HAND):
        BASELINES["axis-in-turn"](scenario, 3)
    made = baseline_sequences(scenario, 3)
    assert list(made) == list(BASELINES)
    assert isinstance(made["axis-in-turn"], str) and SAME_AS_HAND in made["axis-in-turn"]
    assert made["hand-designed"].tolist() == [[4, 0]] * 3  # type: ignore[union-attr]
    settings = ScorerSettings(n_realisations=4, metric="euclidean")
    compared = compare_with_baselines(scenario, 3, settings, seed=3, n_draws=1)
    assert set(compared["axis-in-turn"]) == {"unavailable"}
    assert SAME_AS_HAND in compared["axis-in-turn"]["unavailable"]
    assert "fresh_f1" in compared["hand-designed"]


def test_short_lengths_list_what_exists_and_why_the_rest_do_not(paper: Scenario) -> None:
    made = baseline_sequences(paper, 1)
    assert made["hand-designed"].tolist() == [[4, 4, 4, 0, 0, 0]]  # type: ignore[union-attr]
    assert made["axis-in-turn"].tolist() == [[4, 0, 0, 0, 0, 0]]  # type: ignore[union-attr]
    assert made["fire-then-brake"] == "fire then brake needs at least 2 steps, got 1"
    assert made["fire-coast-brake"] == "fire, coast, brake needs at least 3 steps, got 1"
    with pytest.raises(ValueError, match="got 0"):
        baseline_sequences(paper, 0)


def test_fire_coast_brake_that_repeats_fire_then_brake_is_unavailable(paper: Scenario) -> None:
    # At 3 steps both are one fire, one coast, one brake: it was scored (and listed) twice.
    made = baseline_sequences(paper, 3)
    fire, off, brake = [4, 4, 4, 0, 0, 0], [0] * 6, [0, 0, 0, 4, 4, 4]
    assert made["fire-then-brake"].tolist() == [fire, off, brake]  # type: ignore[union-attr]
    assert made["fire-coast-brake"] == (
        "the same sequence as fire-then-brake at 3 steps (one step each of fire, coast and brake)"
    )
    # From 4 steps on they differ, and both are listed.
    four = baseline_sequences(paper, 4)
    assert four["fire-coast-brake"].tolist() == [fire, off, off, brake]  # type: ignore[union-attr]
    assert four["fire-then-brake"].tolist() == [fire, fire, brake, brake]  # type: ignore[union-attr]
