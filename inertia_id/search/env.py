"""The paper's sequence-search environment (Gymnasium)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from ..errors import InputError
from ..physics.scenario import Scenario
from .scorer import PrefixScorer, ScorerSettings

__all__ = ["ENV_ID", "SequenceSearchEnv"]

ENV_ID = "InertiaId/SequenceSearch-v0"


class SequenceSearchEnv(gym.Env[np.ndarray, np.ndarray]):
    """Build an actuation sequence step by step; the reward says how separable it is.

    One episode builds a sequence of ``sequence_length`` (L) steps for the scenario's N
    thrusters, each fired at one of M duty levels. The agent never sees the spacecraft:
    it chooses the next row of the sequence from the rows chosen so far.

    ============  ===========================================================================
    Observation   ``MultiDiscrete([M + 1] * (L * N))``: the actuation history, row-major;
                  entry ``i * N + j`` is the level index of thruster j at step i, or M for
                  steps not taken yet.
    Action        ``MultiDiscrete([M] * N)``: one level index per thruster for the next step.
    Reward        Steps before the last: ``-1 + 3 F1``, with F1 the clustering score of the
                  candidates' responses to the prefix so far (or, with the objective
                  "separability", the separability score). Last step: ``-|ω_final|``, the
                  mean final rate over every candidate and realisation, rad/s (the paper's
                  detumbling term). Every step also subtracts ``fuel_weight`` times the
                  angular impulse it commands, N m s (the paper's multi-objective variant).
                  The constrained variant (``constraints`` given): the last step also
                  subtracts ``constraint_penalty`` times the summed relative violation
                  of the constraints (``Σ max(0, (value − bound) / max(bound,
                  scale))``, the scale :data:`~inertia_id.search.objectives.
                  CONSTRAINT_SCALES` gives: a bound of 0 is no special case), a penalty whose
                  multiplier a Lagrangian PPO raises while episodes violate them.
    Episode end   Terminated after L steps; never truncated.
    Info          ``f1`` (the objective's score), ``accuracy``, ``final_rate_rad_s``
                  (mean |ω| when the prefix's last command ends, the reward's),
                  ``residual_rate_rad_s`` (once the lag has delivered the torque still
                  in it, mean over candidates: the operator's residual rate),
                  ``fuel_nms`` (the prefix's impulse), ``step_fuel_nms``, ``step``,
                  ``sequence`` (the prefix), ``objective``, ``error_bound``
                  (separability only, else None), ``peak_rate_rad_s`` and
                  ``constraint_violation`` (the summed relative violation).
    ============  ===========================================================================

    Every candidate and realisation is simulated at each step (extending the previous
    step's state), on noise drawn once per seed (``noise="fixed"``: common random
    numbers, so sequences are compared on the same draws and scores are cached) or anew
    every episode (``noise="fresh"``).

    :param scenario: the spacecraft (default: the paper preset).
    :param sequence_length: L, actuation steps per episode.
    :param fuel_weight: reward cost per N m s of commanded impulse.
    :param noise: "fixed" or "fresh", see above.
    :param seed: noise seed; ``reset(seed=...)`` draws new noise from that seed.
    :param constraints: bounds on the physical figures of the whole sequence, by the
        names of :data:`~inertia_id.search.objectives.CONSTRAINTS` (all but
        ``min_accuracy``, which the prefix score does not measure).
    :param constraint_penalty: reward cost per unit of summed relative violation.
    :param settings: how prefixes are simulated and scored (realisations, objective,
        metric, DTW band, k-means runs); keyword arguments of :class:`ScorerSettings`
        may be given instead.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (Gymnasium's protocol)

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        sequence_length: int = 4,
        fuel_weight: float = 0.0,
        noise: str = "fixed",
        seed: int | None = None,
        settings: ScorerSettings | None = None,
        constraints: dict[str, float] | None = None,
        constraint_penalty: float = 0.0,
        **settings_kwargs: Any,
    ) -> None:
        super().__init__()
        if settings is not None and settings_kwargs:
            raise InputError("give either settings or its keyword arguments, not both")
        settings = settings or ScorerSettings(**settings_kwargs)
        if not (np.isfinite(fuel_weight) and fuel_weight >= 0):
            raise InputError(f"fuel_weight must be finite and >= 0, got {fuel_weight!r}")
        if noise not in ("fixed", "fresh"):
            raise InputError(f"noise must be 'fixed' or 'fresh', got {noise!r}")
        self.scenario = scenario or Scenario.paper()
        from .objectives import check_constraints, check_per_flight_realisations

        self.constraints = check_constraints(constraints, self.scenario)
        if "min_accuracy" in self.constraints:
            raise InputError(
                "the sequence-search environment cannot constrain min_accuracy; use the "
                "Pareto search (method nsga2) for an accuracy bound"
            )
        check_per_flight_realisations(self.constraints, settings.n_realisations)
        if not (np.isfinite(constraint_penalty) and constraint_penalty >= 0):
            raise InputError(
                f"constraint_penalty must be finite and >= 0, got {constraint_penalty!r}"
            )
        #: The penalty multiplier (a Lagrangian PPO updates it between rollouts).
        self.constraint_penalty = float(constraint_penalty)
        self.sequence_length = sequence_length
        self.fuel_weight = float(fuel_weight)
        self.noise = noise
        self.scorer = PrefixScorer(self.scenario, sequence_length, settings, seed=seed)
        n, m = self.scenario.n_thrusters, self.scenario.n_levels
        self.observation_space = spaces.MultiDiscrete(np.full(sequence_length * n, m + 1))
        self.action_space = spaces.MultiDiscrete(np.full(n, m))
        self._prefix: list[tuple[int, ...]] = []
        self._episodes = 0
        if seed is not None:
            # Fresh-noise episodes draw their seeds from np_random: seed it too, so the
            # constructor's seed alone fixes every episode.
            self._np_random, self._np_random_seed = seeding.np_random(seed)

    @property
    def settings(self) -> ScorerSettings:
        return self.scorer.settings

    def _observation(self) -> np.ndarray:
        n, m = self.scenario.n_thrusters, self.scenario.n_levels
        obs = np.full((self.sequence_length, n), m, dtype=np.int64)
        if self._prefix:
            obs[: len(self._prefix)] = self._prefix
        return obs.reshape(-1)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:
            self.scorer.reseed(seed)
        elif self.noise == "fresh" and self._episodes > 0:
            self.scorer.reseed(int(self.np_random.integers(2**63 - 1)))
        self._prefix = []
        self._episodes += 1
        return self._observation(), {}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if len(self._prefix) >= self.sequence_length:
            raise RuntimeError("the episode has ended; call reset()")
        levels = np.asarray(action).reshape(-1)
        if not self.action_space.contains(levels.astype(np.int64)) or np.any(
            levels != np.round(levels)
        ):
            raise InputError(
                f"action must be {self.scenario.n_thrusters} level indices in "
                f"0..{self.scenario.n_levels - 1}, got {np.asarray(action).tolist()}"
            )
        self._prefix.append(tuple(int(v) for v in levels))
        score = self.scorer.score(self._prefix)
        last = len(self._prefix) == self.sequence_length
        reward = -score.final_rate_rad_s if last else -1.0 + 3.0 * score.f1
        reward -= self.fuel_weight * score.step_impulse_nms
        violation = self._violation(score) if last else 0.0
        reward -= self.constraint_penalty * violation
        info = {
            "f1": score.f1,
            "accuracy": score.accuracy,
            "final_rate_rad_s": score.final_rate_rad_s,
            "residual_rate_rad_s": score.residual_rate_rad_s,
            "fuel_nms": score.impulse_nms,
            "step_fuel_nms": score.step_impulse_nms,
            "step": len(self._prefix),
            "sequence": [list(row) for row in self._prefix],
            "objective": score.objective,
            "error_bound": score.error_bound,
            "peak_rate_rad_s": score.peak_rate_rad_s,
            "constraint_violation": violation,
        }
        return self._observation(), float(reward), last, False, info

    def _violation(self, score: Any) -> float:
        """Summed relative violation of the constraints by the whole sequence (0: all hold)."""
        if not self.constraints:
            return 0.0
        from .objectives import CONSTRAINTS, constraint_violation

        prefix = self._prefix
        figures = {
            "final_rate_rad_s": score.final_rate_rad_s,
            "final_rate_max_rad_s": score.final_rate_max_rad_s,
            "final_rate_p95_rad_s": score.final_rate_p95_rad_s,
            "peak_rate_rad_s": score.peak_rate_rad_s,
            "peak_rate_p95_rad_s": score.peak_rate_p95_rad_s,
            "commanded_residual_rate_rad_s": score.commanded_residual_rate_rad_s,
            "commanded_residual_rate_max_rad_s": score.commanded_residual_rate_max_rad_s,
            "impulse_nms": score.impulse_nms,
            "on_time_s": float(self.scenario.on_time_s(prefix).sum()),
            "propellant_kg": self.scenario.propellant_kg(prefix),
            "duration_s": self.scenario.duration_s(prefix),
        }
        total = 0.0
        for name, bound in self.constraints.items():
            value = figures[CONSTRAINTS[name][0]]
            assert value is not None  # checked against the scenario at construction
            total += max(0.0, constraint_violation(name, value, bound))
        return float(total)
