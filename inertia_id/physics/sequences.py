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
  equally aligned sets the largest torque), at full duty. A set qualifies when every
  thruster in it enlarges the set's summed torque (without it the sum would be smaller):
  none works against the others, so two thrusters 109.5 degrees apart (a tetrahedral
  set) that together give a pure axis torque qualify, while two nearly opposite ones,
  whose sum is a sliver of what they burn, do not. With canted thrusters that is often a
  pair, never the same set for two axes unless the geometry allows nothing else. Where
  the geometry makes it the hand-designed sequence itself, the registered baseline
  (:data:`BASELINES`, what searches score and the API lists) says so and is unavailable,
  rather than scored twice.
- :func:`fire_then_brake`: the hand-designed thrusters for the first half, then the
  brake: duties (duty levels) that cancel the fired torque, from a least squares over
  the thrusters with every duty between 0 and full (:func:`brake_duties`); an odd step in
  the middle coasts. Fire and brake are chosen together (:func:`fire_and_brake`): the
  fire runs at the largest duty level whose brake, on the levels, cancels it to within
  1 % (full duty where the brake is as strong as the fire), or else at the level whose
  brake cancels it best, so a brake weaker than the fire still ends near rest. Where no
  duties of the thrusters, however large, give the opposite of the fired torque (all of
  them push one way about some axis: three on one side of the body), there is no brake,
  and this baseline and the next are unavailable, saying along which direction.
- :func:`fire_coast_brake`: fire for a quarter of the steps (at least one), coast, brake
  for as many: the same propellant as fire-then-brake of twice the fire steps' length
  spends, held at rate longer (coasting costs nothing). At 3 steps it is fire-then-brake
  itself, so the registered baseline is unavailable there.

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
    "baseline_sequences",
    "brake_duties",
    "fire_and_brake",
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
# A brake that leaves at most this fraction of the fired torque uncancelled cancels it:
# the rate it leaves is about as small a fraction of the peak rate (on an irregular
# geometry duty levels seldom cancel exactly, and a smaller fire would excite less).
_CANCELLED = 0.01


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


def _cooperates(torque: np.ndarray, subset: tuple[int, ...] | list[int]) -> bool:
    """Whether every thruster of ``subset`` enlarges the set's summed torque: the set
    without it gives a smaller torque, ``|T - t_j| < |T|``, that is ``t_j . T > |t_j|^2 / 2``
    (``T`` the summed torque, ``t_j`` the thruster's).

    A thruster whose removal leaves at least as large a torque cancels at least as much of
    the others' torque as it adds: it works against them and only burns propellant. Two
    thrusters 90 degrees apart or closer always cooperate (every set the old pairwise
    rule allowed still qualifies); so do two of equal torque up to 120 degrees apart, a
    tetrahedral pair (109.5 degrees) summing to a pure axis torque among them. Two nearly
    opposite thrusters do not (fired together they give a sliver of torque at right angles
    to both, however well that sliver is aligned), nor does such a pair hidden in a larger
    set beside a thruster that tilts the sum.
    """
    columns = torque[:, list(subset)]
    total = columns.sum(axis=1)
    squares = (columns**2).sum(axis=0)
    return bool(np.all(total @ columns - squares / 2 > _COSINE_TIE * squares))


def _subsets(torque: np.ndarray) -> list[tuple[int, ...]]:
    """Every thruster set in which each thruster enlarges the set's summed torque
    (:func:`_cooperates`): no thruster works against the others."""
    n = torque.shape[1]
    return [
        s
        for size in range(1, n + 1)
        for s in combinations(range(n), size)
        if _cooperates(torque, s)
    ]


def _best_aligned(torque: np.ndarray, direction: np.ndarray) -> tuple[int, ...]:
    """The thruster set (every thruster enlarging the set's torque) whose summed
    full-duty torque is best aligned with ``direction``; among equally aligned sets, the
    one with the largest torque."""
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
                if j not in chosen_list and _cooperates(torque, [*chosen_list, j])
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

    The duties are the bounded least-squares solution of ``A d = -torque`` with every
    duty between 0 and full (a brake that needs more than one thruster's full duty
    spreads over those beside it rather than being clipped), rounded to the nearest duty
    level; then, while moving one of those thrusters a level up or down shrinks the
    torque left over, it is moved.
    """
    from scipy.optimize import lsq_linear

    matrix = scenario.torque_matrix
    target = np.asarray(torque_nm, dtype=float)
    levels = scenario.level_values
    if not np.any(target):
        return np.zeros(scenario.n_thrusters, dtype=int)
    duty = lsq_linear(matrix, -target, bounds=(0.0, 1.0), method="bvls").x
    row = np.abs(duty[:, None] - levels[None, :]).argmin(axis=1)
    braking = np.flatnonzero(duty > _COSINE_TIE)
    left = target + matrix @ levels[row]
    for _ in range(row.size * (levels.size - 1)):  # each pass shrinks the leftover
        best_size, best_move = float(np.linalg.norm(left)), None
        for j in braking:
            for step in (-1, 1):
                level = row[j] + step
                if 0 <= level < levels.size:
                    moved = left + matrix[:, j] * (levels[level] - levels[row[j]])
                    size = float(np.linalg.norm(moved))
                    if size < best_size - _COSINE_TIE * float(np.linalg.norm(target)):
                        best_size, best_move = size, (j, level, moved)
        if best_move is None:
            break
        j, row[j], left = best_move
    return row


def hand_designed(scenario: Scenario, length: int) -> np.ndarray:
    """The principal-diagonal thrusters at full duty on every step, (length, N) levels."""
    _check_length(length)
    return np.tile(_fire_row(scenario), (int(length), 1))


def axis_in_turn(scenario: Scenario, length: int) -> np.ndarray:
    """One principal axis per step (1, 2, 3, 1, ...), driven by its best-aligned set.

    Defined on every geometry that gives each axis some torque, even where that makes it
    the hand-designed sequence; :data:`BASELINES` then reports it unavailable."""
    _check_length(length)
    axes = principal_axes(scenario)
    rows = [_full(scenario, _best_aligned(scenario.torque_matrix, axis)) for axis in axes]
    return np.stack([rows[step % 3] for step in range(int(length))])


def _check_reversible(torque_matrix: np.ndarray, fired_nm: np.ndarray) -> None:
    """Raise :class:`InputError` unless some non-negative duties (of any size) give the
    opposite of ``fired_nm`` (3,), N m: else no brake, however strong, stops the fire.

    Where the thrusters all push one way about some axis (three on one side of the
    body, or eight canted ones that all torque +z), the "brake" of least squares was the
    thruster nearest to opposing the fire, which left 62-100 % of the fired torque (3-6
    thrusters with +z torques, 23 geometries) and on three thrusters on one side added
    z torque: a fire-then-brake that ends spinning. The message names a direction along
    which no thruster gives a negative torque (a body axis where one is).
    """
    from scipy.optimize import linprog

    scale = float(np.abs(torque_matrix).max())
    opposite = linprog(
        np.zeros(torque_matrix.shape[1]),
        A_eq=torque_matrix / scale,
        b_eq=-fired_nm / scale,
        bounds=(0.0, None),
        method="highs",
    )
    if opposite.status != 2:  # 2: infeasible
        return
    # A direction along which every thruster's torque is >= 0 and the fire's > 0 exists
    # (Farkas): a body axis where one is, else one a linear program finds.
    along = None
    for axis in range(3):
        for sign, name in ((1.0, "+"), (-1.0, "-")):
            if sign * fired_nm[axis] > 0 and np.all(sign * torque_matrix[axis] >= 0):
                along = along or f"body {name}{'xyz'[axis]}"
    if along is None:
        certificate = linprog(
            -fired_nm / scale,
            A_ub=-torque_matrix.T / scale,
            b_ub=np.zeros(torque_matrix.shape[1]),
            bounds=(-1.0, 1.0),
            method="highs",
        )
        if certificate.status == 0:
            along = str(np.round(certificate.x / np.linalg.norm(certificate.x), 3).tolist())
    words = (
        f"every thruster's torque has a component of 0 or more along {along}, the fire's a "
        "positive one, so"
        if along is not None
        else "no duties give its opposite, so"
    )
    raise InputError(
        f"the thrusters cannot reverse the fired torque {np.round(fired_nm, 3).tolist()} "
        f"N m: {words} there is no brake on this geometry"
    )


def fire_and_brake(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """The fire step and the brake step that cancels it, level indices, each (N,).

    The fire is the hand-designed thrusters, all at one duty level; the brake is
    :func:`brake_duties` for its torque (at most full duty, on the levels). Each fire
    level is tried from full duty downwards: the first whose brake leaves at most 1 % of
    the fired torque is kept, the most torque among near-exact cancellations; failing
    any, the one whose brake leaves the smallest net torque relative to the fired torque
    (the larger level on a tie). A brake as strong as the fire gives full duty, the
    hand-designed step (the paper preset: ``[4, 4, 4, 0, 0, 0]`` then
    ``[0, 0, 0, 4, 4, 4]``); a weaker one scales the fire down to what it can stop, rather
    than leaving the body spinning on a clipped brake.
    """
    thrusters = _fire_row(scenario) > 0
    torque_matrix = scenario.torque_matrix
    _check_reversible(torque_matrix, torque_matrix @ thrusters.astype(float))
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for level in range(scenario.n_levels - 1, 0, -1):
        fire_row = thrusters * level
        fired = torque_matrix @ scenario.level_values[fire_row]
        brake_row = brake_duties(scenario, fired)
        net = fired + torque_matrix @ scenario.level_values[brake_row]
        left = float(np.linalg.norm(net)) / float(np.linalg.norm(fired))
        if left <= _CANCELLED:
            return fire_row, brake_row
        if best is None or left < best[0] - _COSINE_TIE:
            best = (left, fire_row, brake_row)
    assert best is not None  # at least two levels: one fire level was tried
    return best[1], best[2]


def _fire_coast_brake(scenario: Scenario, fire: int, coast: int) -> np.ndarray:
    fire_row, brake_row = fire_and_brake(scenario)
    if not brake_row.any():
        raise InputError("no thruster opposes the fired torque; there is no brake")
    coast_row = np.zeros(scenario.n_thrusters, dtype=int)
    return np.stack([fire_row] * fire + [coast_row] * coast + [brake_row] * fire)


def fire_then_brake(scenario: Scenario, length: int) -> np.ndarray:
    """Fire the hand-designed thrusters for half the steps, brake for as many (an odd
    middle step coasts); needs at least 2 steps, and thrusters that can reverse the fired
    torque. The fire's duty is the largest the brake can cancel (:func:`fire_and_brake`):
    full duty, the hand-designed step, unless the brake is weaker."""
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


def _distinct_axis_in_turn(scenario: Scenario, length: int) -> np.ndarray:
    """:func:`axis_in_turn`, unless it is the hand-designed sequence itself (a geometry
    with one thruster set best aligned with every axis and the diagonal alike)."""
    sequence = axis_in_turn(scenario, length)
    try:
        same = np.array_equal(sequence, hand_designed(scenario, length))
    except InputError:
        same = False
    if same:
        raise InputError(
            "the same sequence as hand-designed on this geometry (no thruster set drives "
            "one principal axis better than the hand-designed step)"
        )
    return sequence


def _distinct_fire_coast_brake(scenario: Scenario, length: int) -> np.ndarray:
    """:func:`fire_coast_brake`, unless it is fire-then-brake itself (at 3 steps both
    fire once, coast once and brake once)."""
    sequence = fire_coast_brake(scenario, length)
    if np.array_equal(sequence, fire_then_brake(scenario, length)):
        raise InputError(
            f"the same sequence as fire-then-brake at {length} steps (one step each of "
            "fire, coast and brake)"
        )
    return sequence


#: The baselines by name, in the order they are reported. A geometry or a length that
#: does not allow one makes it raise :class:`~inertia_id.errors.InputError` saying why;
#: so does an axis-in-turn that would repeat hand-designed, and a fire-coast-brake that
#: would repeat fire-then-brake (at 3 steps).
BASELINES = {
    "hand-designed": hand_designed,
    "axis-in-turn": _distinct_axis_in_turn,
    "fire-then-brake": fire_then_brake,
    "fire-coast-brake": _distinct_fire_coast_brake,
}


def baseline(name: str, scenario: Scenario, length: int) -> np.ndarray:
    """A baseline sequence by name (:data:`BASELINES`: an axis-in-turn that repeats
    hand-designed raises, like a length or a geometry that does not allow one)."""
    if name not in BASELINES:
        raise InputError(f"baseline must be one of {sorted(BASELINES)}, got {name!r}")
    return BASELINES[name](scenario, length)


def baseline_sequences(scenario: Scenario, length: int) -> dict[str, np.ndarray | str]:
    """Every baseline of ``length`` steps by name (:data:`BASELINES` order): its sequence
    (level indices, (length, N)), or, for one the length or the geometry does not allow,
    why it is unavailable. A length that is no positive integer is an error."""
    _check_length(length)
    out: dict[str, np.ndarray | str] = {}
    for name, make in BASELINES.items():
        try:
            out[name] = make(scenario, length)
        except InputError as exc:
            out[name] = str(exc)
    return out
