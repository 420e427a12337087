"""Firings that cancel among themselves (:class:`OpposedFirings`): a step's thrusters
whose torques sum to zero in part spend on-time and propellant for no torque. The
searches take that part off every sequence they score; a command plan warns about a
sequence that keeps it.
"""

from __future__ import annotations

import threading

import numpy as np

from ..physics.scenario import Scenario

__all__ = ["OpposedFirings", "cancelling_warning"]


class OpposedFirings:
    """Takes off what a step's firings cancel among themselves: each step's duties
    reduced (none raised) while a set of its fired thrusters whose torques cancel can
    give up a common part on the duty levels, the same net torque for less on-time, so
    less propellant and less duty jitter for the same response.

    On a geometry where only pairs cancel (the paper's), a thruster and its exact
    opposite (torques equal and opposite to 1e-9 of their size) lose their common part
    at once, on every step together (each pair's duties then differ by as much). Before,
    NSGA-II's fronts kept such firings (paper preset, L = 4: 4 to 8 of 27-35 members,
    +y and -y both at full duty in one step, 4 N m s for no torque), each dominated by
    its twin that the search never tried: its crossover and mutation change one level
    at a time.

    Any other cancelling set is found once per geometry: every set of 1 to 4 thrusters
    (a minimal one in three dimensions has at most 4) whose torques have a positive
    combination ``v`` summing to zero (to :data:`SAME_TORQUE`), all four of a tetrahedral
    set, three thrusters 120 degrees apart, a thruster whose thrust passes through the
    centre of mass (no torque: on seven thrusters, the paper's six and one such, 30 and
    33 of 59-60 front members fired it, L = 2, seeds 0-1, on-time and propellant for
    nothing), and on which some multiple of ``v`` is a
    difference of duty levels on every thruster. A step then gives up the largest such
    multiple that leaves each duty on a level, the set that saves the most on-time
    first, until none can. Before, the pairs were all it handled: on four tetrahedral
    thrusters 3-5 % of the sequences an NSGA-II search scored (L = 4, population 64, 30
    generations) held a step with all four on, ``[2, 2, 2, 2]`` firing 4 N m s for no
    torque. On a geometry whose cancelling combinations fit no levels (most irregular
    ones) nothing is kept, so it costs nothing per step.
    """

    #: Two net torques are the same within this fraction of the largest thruster torque:
    #: far below any duty jitter (2 % on the paper preset), above a torque matrix's
    #: rounding as typed.
    SAME_TORQUE = 1e-6
    #: A duty within this of a level is on it.
    ON_LEVEL = 1e-9

    def __init__(self, scenario: Scenario) -> None:
        torque = scenario.torque_matrix
        sizes = np.linalg.norm(torque, axis=0)
        n = scenario.n_thrusters
        self.pairs = [
            (j, k)
            for j in range(n)
            for k in range(j + 1, n)
            if max(sizes[j], sizes[k]) > 0
            and np.linalg.norm(torque[:, j] + torque[:, k]) <= 1e-9 * max(sizes[j], sizes[k])
        ]
        duty = scenario.level_values
        self.duty = duty
        # difference[a, b]: the level whose duty is duty[a] - duty[b], or -1.
        gap = duty[:, None] - duty[None, :]
        close = np.abs(gap[:, :, None] - duty[None, None, :]) <= self.ON_LEVEL
        self.difference = np.where(close.any(axis=2), close.argmax(axis=2), -1)
        largest = float(sizes.max()) if sizes.size else 0.0
        unit = torque / largest if largest > 0 else torque
        #: The cancelling sets: (thrusters, bit mask, v with its largest entry 1, the
        #: multiples of v that are level differences on each thruster, largest first).
        self.sets = _geometry_sets(unit, duty, self.SAME_TORQUE, self.ON_LEVEL)
        self._pairs_only = all(len(thrusters) == 2 for thrusters, *_ in self.sets)
        #: Each step reduced so far (its level indices' bytes) and its reduced levels.
        self._reduced: dict[bytes, np.ndarray] = {}

    def __call__(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` (..., N) of level indices with every step's cancelling part taken
        off; a new array."""
        out = np.array(rows, dtype=int, copy=True)
        # Where only pairs cancel (the paper's geometry) they are disjoint or share a
        # thruster the same way whatever the order: taken off at once. Elsewhere the set
        # that saves the most goes first: on eight thrusters in opposite pairs along the
        # tetrahedral directions, [4, 4, 4, 4, 4, 0, 0, 0] is thruster 5 alone, not the
        # [0, 4, 4, 4, 0, 0, 0, 0] its pair taken off first would leave.
        for j, k in self.pairs if self._pairs_only else ():
            a, b = out[..., j], out[..., k]
            first = a >= b
            left = np.where(first, self.difference[a, b], self.difference[b, a])
            take = (a > 0) & (b > 0) & (left >= 0)
            out[..., j] = np.where(take, np.where(first, left, 0), a)
            out[..., k] = np.where(take, np.where(first, 0, left), b)
        if self._pairs_only or not out.size:
            return out
        steps = out.reshape(-1, out.shape[-1])
        unique, inverse = np.unique(steps, axis=0, return_inverse=True)
        reduced = np.array([self._reduce(step) for step in unique])
        return reduced[inverse.reshape(-1)].reshape(out.shape)

    def _reduce(self, step: np.ndarray) -> np.ndarray:
        """One step's levels with its cancelling sets' common parts taken off."""
        key = step.tobytes()
        if key in self._reduced:
            return self._reduced[key]
        row = step.copy()
        while True:
            fired = int(sum(1 << int(j) for j in np.flatnonzero(row > 0)))
            best: tuple[float, np.ndarray, np.ndarray] | None = None
            for thrusters, mask, v, multiples in self.sets:
                if mask & ~fired:
                    continue
                duties = self.duty[row[thrusters]]
                for multiple in multiples[multiples <= (duties / v).min() + self.ON_LEVEL]:
                    left = duties - multiple * v
                    nearest = np.abs(left[:, None] - self.duty[None, :]).argmin(axis=1)
                    if np.all(np.abs(self.duty[nearest] - left) <= self.ON_LEVEL):
                        saved = float(duties.sum() - self.duty[nearest].sum())
                        if best is None or saved > best[0] + self.ON_LEVEL:
                            best = (saved, thrusters, nearest)
                        break
            if best is None:
                break
            row[best[1]] = best[2]
        self._reduced[key] = row
        return row


#: The cancelling sets of the geometries seen last (a plan request finds its scenario's
#: again: 0.9-1.7 s on 24 thrusters), by their torque matrix and duty levels.
_GEOMETRIES: dict[bytes, list[tuple[np.ndarray, int, np.ndarray, np.ndarray]]] = {}
_GEOMETRIES_KEPT = 16
_GEOMETRIES_LOCK = threading.Lock()


def _geometry_sets(
    unit_torque: np.ndarray, duty: np.ndarray, same: float, on_level: float
) -> list[tuple[np.ndarray, int, np.ndarray, np.ndarray]]:
    """:func:`_cancelling_sets`, found once per geometry (the last few kept)."""
    key = b"|".join(
        [
            np.ascontiguousarray(unit_torque).tobytes(),
            duty.tobytes(),
            repr((same, on_level)).encode(),
        ]
    )
    with _GEOMETRIES_LOCK:  # the API plans on several threads
        found = _GEOMETRIES.get(key)
    if found is None:
        found = _cancelling_sets(unit_torque, duty, same, on_level)
        with _GEOMETRIES_LOCK:
            while len(_GEOMETRIES) >= _GEOMETRIES_KEPT:
                _GEOMETRIES.pop(next(iter(_GEOMETRIES)))
            _GEOMETRIES[key] = found
    return found


def _cancelling_sets(
    unit_torque: np.ndarray, duty: np.ndarray, same: float, on_level: float
) -> list[tuple[np.ndarray, int, np.ndarray, np.ndarray]]:
    """The minimal sets of 1 to 4 thrusters whose torques (``unit_torque``, 3 x N, in
    units of the largest) have a positive combination ``v`` summing to zero within
    ``same``, each with the multiples of ``v`` (largest entry 1) that are a difference
    of two duty levels on every one of its thrusters, largest first; sets with none
    are left out."""
    from itertools import combinations

    n = unit_torque.shape[1]
    gaps = np.unique((duty[:, None] - duty[None, :])[duty[:, None] > duty[None, :]])
    found: list[tuple[np.ndarray, int, np.ndarray, np.ndarray]] = []
    for size in range(1, min(n, 4) + 1):
        for subset in combinations(range(n), size):
            mask = sum(1 << j for j in subset)
            if any(other & mask == other for _, other, _, _ in found):
                continue  # holds a smaller cancelling set
            columns = unit_torque[:, subset]
            _, singular, basis = np.linalg.svd(columns)
            if size - int(np.count_nonzero(singular > same)) != 1:
                continue
            v = basis[-1] * np.sign(basis[-1][np.argmax(np.abs(basis[-1]))])
            if not np.all(v > same):
                continue
            v = v / v.max()
            # Multiples m with m v_j a level difference for every thruster j.
            multiples = gaps / v[0]
            for share in v[1:]:
                scaled = multiples * share
                nearest = np.abs(scaled[:, None] - gaps[None, :]).min(axis=1)
                multiples = multiples[nearest <= on_level]
            if len(multiples) and np.linalg.norm(columns @ v) <= same:
                found.append((np.array(subset), mask, v, np.sort(multiples)[::-1]))
    return found


def cancelling_warning(scenario: Scenario, rows: np.ndarray, shown: int = 5) -> str | None:
    """A sentence naming the steps of ``rows`` (L, N level indices) that fire thrusters
    whose torques cancel in part (or a thruster that gives no torque), each with the
    levels that give the same torque for less on-time and what that saves; None when no
    step does. A sequence a search found has none (:class:`OpposedFirings` took it off);
    one typed by hand may: it spends propellant and adds duty jitter for no torque."""
    rows = np.asarray(rows, dtype=int)
    reduced = OpposedFirings(scenario)(rows)
    changed = np.flatnonzero((reduced != rows).any(axis=1))
    if not len(changed):
        return None
    step_s = scenario.timing.step_duration_s
    saved_s = (scenario.level_values[rows] - scenario.level_values[reduced]).sum(axis=1) * step_s
    impulse = scenario.impulse_nms(rows) - scenario.impulse_nms(reduced)
    listed = "; ".join(
        f"step {i + 1} {rows[i].tolist()}: {reduced[i].tolist()} gives the same torque "
        f"with {saved_s[i]:.3g} s less on-time"
        for i in changed[:shown]
    )
    more = f"; and {len(changed) - shown} more steps" if len(changed) > shown else ""
    # A thruster that gives no torque (thrust through the centre of mass) is a set of
    # one: named as such, not as cancelling.
    fired_idle = [j + 1 for j in scenario.idle_thrusters if (rows[changed, j] > 0).any()]
    what = (
        ("fires" if len(changed) == 1 else "fire")
        + " thrusters whose torques cancel in part"
        + (
            f" or thruster {', '.join(map(str, fired_idle))}, which gives no torque"
            if fired_idle
            else ""
        )
    )
    return (
        f"{len(changed)} step{'' if len(changed) == 1 else 's'} {what}: {listed}{more}; in "
        f"all {impulse:.3g} N m s of impulse for no torque, which costs propellant and adds "
        "duty jitter"
    )
