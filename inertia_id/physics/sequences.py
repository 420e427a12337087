"""Hand-designed excitation sequences: what a searched sequence must beat.

- :func:`hand_designed`: the thruster that pushes hardest about each positive body axis
  (x, y, z), all three at full duty on every step. On the paper preset this is
  ``[[4, 4, 4, 0, 0, 0]] * L`` and already clusters at F1 = 1 at 1x noise, but it fires
  one fixed torque direction, so it excites little of the inertia tensor.
- :func:`axis_in_turn`: one axis at a time (x, y, z, x, ...), full duty.

A search earns its keep only by beating these on fresh draws: fewer steps, less fuel,
a smaller final rate, or more accuracy at high noise
(:func:`~inertia_id.search.baselines.compare_with_baselines`).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .scenario import Scenario

__all__ = ["BASELINES", "axis_in_turn", "baseline", "hand_designed"]


def _axis_thrusters(scenario: Scenario) -> list[int]:
    """For each body axis, the thruster with the largest positive torque about it."""
    torque = scenario.torque_matrix
    chosen = []
    for axis in range(3):
        column = int(np.argmax(torque[axis]))
        if torque[axis, column] <= 0:
            raise InputError(
                f"no thruster gives a positive torque about body axis {'xyz'[axis]}; "
                "the hand-designed sequences need one per axis"
            )
        chosen.append(column)
    return chosen


def _check_length(length: int) -> None:
    if isinstance(length, bool) or not isinstance(length, int | np.integer) or length < 1:
        raise InputError(f"sequence length must be a positive integer, got {length!r}")


def hand_designed(scenario: Scenario, length: int) -> np.ndarray:
    """The positive-axis thrusters at full duty on every step, (length, N) level indices."""
    _check_length(length)
    row = np.zeros(scenario.n_thrusters, dtype=int)
    row[_axis_thrusters(scenario)] = scenario.n_levels - 1
    return np.tile(row, (int(length), 1))


def axis_in_turn(scenario: Scenario, length: int) -> np.ndarray:
    """One positive-axis thruster per step, x then y then z, at full duty."""
    _check_length(length)
    thrusters = _axis_thrusters(scenario)
    sequence = np.zeros((int(length), scenario.n_thrusters), dtype=int)
    for step in range(int(length)):
        sequence[step, thrusters[step % 3]] = scenario.n_levels - 1
    return sequence


BASELINES = {"hand-designed": hand_designed, "axis-in-turn": axis_in_turn}


def baseline(name: str, scenario: Scenario, length: int) -> np.ndarray:
    """A baseline sequence by name (:data:`BASELINES`)."""
    if name not in BASELINES:
        raise InputError(f"baseline must be one of {sorted(BASELINES)}, got {name!r}")
    return BASELINES[name](scenario, length)
