"""Hand-designed excitation sequences: what a searched sequence must beat.

Defined for any thruster geometry, from the thrusters' torque directions (the columns
of the torque matrix A) and the principal axes of the first candidate (ordered and
signed to match the body axes x, y, z they lie closest to; for a diagonal tensor they are
the body axes):

- :func:`hand_designed`: every thruster whose torque has a positive component along the
  diagonal ``e1 + e2 + e3`` of the principal axes, at full duty, on every step: all
  three axes driven at once with the most torque the thrusters give in that sense. On
  the paper preset this is ``[[4, 4, 4, 0, 0, 0]] * L``.
- :func:`axis_in_turn`: one principal axis per step (1, 2, 3, 1, ...), each driven by
  the thruster set whose summed torque is best aligned with it (the smallest angle; among
  equally aligned sets the largest torque), at full duty. With canted thrusters that is
  often a pair, never the same set for two axes unless the geometry allows nothing else.
- :func:`fire_then_brake`: the hand-designed step for the first half, then the brake:
  duties (nearest duty levels) that cancel the fired torque, from a non-negative least
  squares over the thrusters; an odd step in the middle coasts. It ends near rest.
- :func:`fire_coast_brake`: fire for a quarter of the steps (at least one), coast, brake
  for as many: the same propellant as fire-then-brake of twice the fire steps' length
  spends, held at rate longer (coasting costs nothing).

A search earns its keep only by beating these on fresh draws: fewer steps, less
propellant, a smaller final rate, or more accuracy at high noise
(:func:`~inertia_id.search.baselines.compare_with_baselines`).
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from ..checks import is_integer
from ..errors import InputError
from .scenario import Scenario

__all__ = [
    "BASELINES",
    "axis_in_turn",
    "baseline",
    "brake_duties",
    "fire_coast_brake",
    "fire_then_brake",
    "hand_designed",
    "principal_axes",
]

# Subsets are enumerated exactly up to this many thrusters (2^12 = 4096 sets); beyond,
# sets are grown greedily.
_EXACT_SUBSETS = 12
# Two sets whose torque directions differ by less than this cosine are equally aligned.
_COSINE_TIE = 1e-9


def _check_length(length: int) -> None:
    if not is_integer(length, minimum=1):
        raise InputError(f"sequence length must be a positive integer, got {length!r}")


def principal_axes(scenario: Scenario) -> np.ndarray:
    """Principal axes of the first candidate as rows, (3, 3): row i is the one closest to
    body axis i (a greedy match on |cosine|), signed to point along it."""
    _, vectors = np.linalg.eigh(scenario.inertia_array[0])
    axes = vectors.T  # rows
    out = np.zeros((3, 3))
    free = [0, 1, 2]
    for body in range(3):
        best = max(free, key=lambda i: abs(axes[i, body]))
        free.remove(best)
        out[body] = axes[best] * (1.0 if axes[best, body] >= 0 else -1.0)
    return out


def _subsets(torque: np.ndarray) -> list[tuple[int, ...]]:
    """Every thruster set in which no thruster works against another (pairwise torques
    at 90 degrees or less): firing opposing thrusters together only burns propellant."""
    n = torque.shape[1]
    opposed = (torque.T @ torque) < -1e-12 * float(np.abs(torque).max()) ** 2
    return [
        s
        for size in range(1, n + 1)
        for s in combinations(range(n), size)
        if not opposed[np.ix_(s, s)].any()
    ]


def _best_aligned(torque: np.ndarray, direction: np.ndarray) -> tuple[int, ...]:
    """The thruster set (no two opposed) whose summed full-duty torque is best aligned
    with ``direction``; among equally aligned sets, the one with the largest torque."""
    n = torque.shape[1]
    unit = direction / np.linalg.norm(direction)
    if n <= _EXACT_SUBSETS:
        best: tuple[float, float, tuple[int, ...]] | None = None
        tiny = 1e-9 * float(np.abs(torque).max())
        for subset in _subsets(torque):
            total = torque[:, list(subset)].sum(axis=1)
            size = float(np.linalg.norm(total))
            if size <= tiny:
                continue
            cosine = float(total @ unit) / size
            key = (round(cosine / _COSINE_TIE) * _COSINE_TIE, float(total @ unit), subset)
            if best is None or key[:2] > best[:2]:
                best = key
        chosen = best[2] if best is not None else ()
    else:
        chosen_list: list[int] = []
        cosine = -np.inf
        while True:
            options = [
                j
                for j in range(n)
                if j not in chosen_list
                and all(float(torque[:, j] @ torque[:, i]) >= 0 for i in chosen_list)
            ]
            scored = []
            for j in options:
                total = torque[:, [*chosen_list, j]].sum(axis=1)
                size = float(np.linalg.norm(total))
                if size > 0:
                    scored.append((float(total @ unit) / size, j))
            if not scored:
                break
            top, j = max(scored)
            if top <= cosine + _COSINE_TIE:
                break
            chosen_list.append(j)
            cosine = top
        chosen = tuple(chosen_list)
    if not chosen or float(torque[:, list(chosen)].sum(axis=1) @ unit) <= 0:
        raise InputError(
            f"no set of thrusters gives a torque along {np.round(unit, 3).tolist()}; "
            "the baseline sequences need one"
        )
    return chosen


def _full(scenario: Scenario, thrusters: tuple[int, ...] | list[int]) -> np.ndarray:
    row = np.zeros(scenario.n_thrusters, dtype=int)
    row[list(thrusters)] = scenario.n_levels - 1
    return row


def _fire_row(scenario: Scenario) -> np.ndarray:
    """Every thruster with a positive torque component along the principal diagonal."""
    diagonal = principal_axes(scenario).sum(axis=0)
    along = diagonal @ scenario.torque_matrix
    firing = np.flatnonzero(along > 1e-12 * np.abs(scenario.torque_matrix).max())
    if firing.size == 0:
        raise InputError(
            "no thruster gives a torque along the principal diagonal; "
            "the hand-designed sequence needs one"
        )
    return _full(scenario, tuple(int(j) for j in firing))


def brake_duties(scenario: Scenario, torque_nm: np.ndarray) -> np.ndarray:
    """Level indices (N,) whose torque best cancels ``torque_nm`` (3,), N m.

    The duties are the non-negative least-squares solution of ``A d = -torque`` (so only
    thrusters that oppose the torque fire), clipped to full duty and rounded to the
    nearest duty level.
    """
    from scipy.optimize import nnls

    duty, _ = nnls(scenario.torque_matrix, -np.asarray(torque_nm, dtype=float))
    duty = np.minimum(duty, 1.0)
    levels = scenario.level_values
    return np.abs(duty[:, None] - levels[None, :]).argmin(axis=1)


def hand_designed(scenario: Scenario, length: int) -> np.ndarray:
    """The principal-diagonal thrusters at full duty on every step, (length, N) levels."""
    _check_length(length)
    return np.tile(_fire_row(scenario), (int(length), 1))


def axis_in_turn(scenario: Scenario, length: int) -> np.ndarray:
    """One principal axis per step (1, 2, 3, 1, ...), driven by its best-aligned set."""
    _check_length(length)
    axes = principal_axes(scenario)
    rows = [_full(scenario, _best_aligned(scenario.torque_matrix, axis)) for axis in axes]
    return np.stack([rows[step % 3] for step in range(int(length))])


def _fire_coast_brake(scenario: Scenario, fire: int, coast: int) -> np.ndarray:
    fire_row = _fire_row(scenario)
    torque = scenario.torque_matrix @ scenario.level_values[fire_row]
    brake_row = brake_duties(scenario, torque)
    if not brake_row.any():
        raise InputError("no thruster opposes the fired torque; there is no brake")
    coast_row = np.zeros(scenario.n_thrusters, dtype=int)
    return np.stack([fire_row] * fire + [coast_row] * coast + [brake_row] * fire)


def fire_then_brake(scenario: Scenario, length: int) -> np.ndarray:
    """Fire the hand-designed step for half the steps, brake for as many (an odd middle
    step coasts); needs at least 2 steps."""
    _check_length(length)
    if length < 2:
        raise InputError(f"fire then brake needs at least 2 steps, got {length}")
    fire = int(length) // 2
    return _fire_coast_brake(scenario, fire, int(length) - 2 * fire)


def fire_coast_brake(scenario: Scenario, length: int) -> np.ndarray:
    """Fire for a quarter of the steps (at least one), coast, brake for as many as fired;
    needs at least 3 steps (one of each)."""
    _check_length(length)
    if length < 3:
        raise InputError(f"fire, coast, brake needs at least 3 steps, got {length}")
    fire = max(1, int(length) // 4)
    return _fire_coast_brake(scenario, fire, int(length) - 2 * fire)


BASELINES = {
    "hand-designed": hand_designed,
    "axis-in-turn": axis_in_turn,
    "fire-then-brake": fire_then_brake,
    "fire-coast-brake": fire_coast_brake,
}


def baseline(name: str, scenario: Scenario, length: int) -> np.ndarray:
    """A baseline sequence by name (:data:`BASELINES`)."""
    if name not in BASELINES:
        raise InputError(f"baseline must be one of {sorted(BASELINES)}, got {name!r}")
    return BASELINES[name](scenario, length)
