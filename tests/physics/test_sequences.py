"""The hand-designed baseline sequences follow the thruster geometry."""

from __future__ import annotations

import numpy as np
import pytest

from inertia_id import Scenario, simulate
from inertia_id.physics.sequences import axis_in_turn, baseline, hand_designed


def test_the_paper_presets_baselines(paper: Scenario) -> None:
    assert hand_designed(paper, 4).tolist() == [[4, 4, 4, 0, 0, 0]] * 4
    assert axis_in_turn(paper, 4).tolist() == [
        [4, 0, 0, 0, 0, 0],
        [0, 4, 0, 0, 0, 0],
        [0, 0, 4, 0, 0, 0],
        [4, 0, 0, 0, 0, 0],
    ]


def test_they_push_about_each_positive_axis(paper: Scenario) -> None:
    # A torque matrix with its columns shuffled: the baselines follow the thrusters.
    order = [3, 5, 0, 4, 2, 1]
    document = paper.model_dump(mode="json")
    document["thrusters"]["torque_matrix_nm"] = paper.torque_matrix[:, order].tolist()
    shuffled = Scenario.model_validate(document)
    sequence = hand_designed(shuffled, 2)
    result = simulate(shuffled, sequence, 2, np.random.default_rng(0))
    # All three rates grow positive under the positive-axis torques.
    assert np.all(result.omega_true[:, :, -1, :] > 0)
    assert sorted(np.flatnonzero(sequence[0])) == sorted(order.index(j) for j in (0, 1, 2))


def test_bad_names_and_lengths_are_quoted(paper: Scenario) -> None:
    with pytest.raises(ValueError, match="got 'spiral'"):
        baseline("spiral", paper, 4)
    with pytest.raises(ValueError, match="got 0"):
        hand_designed(paper, 0)
