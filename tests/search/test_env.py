"""The sequence-search environment: Gymnasium's API, its spaces, and its reward."""

from __future__ import annotations

import re
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from inertia_id import InputError, Scenario, preset
from inertia_id.physics.simulate import Simulator
from inertia_id.search import ENV_ID, PrefixScorer, ScorerSettings, SequenceSearchEnv

# Three steps of the paper's six thrusters, at varied levels (M = 5: duty 0, .25, .5, .75, 1).
# Commanded impulse per step, |A_j| = 2 N m and 1 s steps: 2 * (sum of duties) N m s.
MIXED_SEQUENCE = [[4, 4, 4, 0, 0, 0], [0, 2, 0, 1, 0, 0], [1, 0, 3, 0, 0, 4]]
MIXED_STEP_IMPULSE_NMS = [6.0, 1.5, 4.0]

SMALL: dict[str, Any] = {"sequence_length": 3, "n_realisations": 5}


def play(
    env: SequenceSearchEnv, sequence: Any, *, seed: int | None = None
) -> tuple[list[float], list[dict[str, Any]]]:
    """Reset and play ``sequence``; the rewards and infos of each step."""
    env.reset(seed=seed)
    rewards, infos = [], []
    for row in sequence:
        _, reward, _, _, info = env.step(np.asarray(row))
        rewards.append(reward)
        infos.append(info)
    return rewards, infos


# Gymnasium's API.


def test_passes_gymnasiums_environment_checker(paper: Scenario) -> None:
    env = gym.make(ENV_ID, scenario=paper, seed=0, **SMALL)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    complaints = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert complaints == []


def test_checker_passes_without_make(paper: Scenario) -> None:
    check_env(SequenceSearchEnv(paper, seed=0, **SMALL), skip_render_check=True)


def test_registered_under_its_id_and_playable_through_make(paper: Scenario) -> None:
    assert ENV_ID in gym.registry
    env = gym.make(ENV_ID, scenario=paper, seed=0, **SMALL)
    assert isinstance(env.unwrapped, SequenceSearchEnv)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    terminated = False
    steps = 0
    while not terminated:
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        assert not truncated
        steps += 1
    assert steps == 3


def test_default_scenario_is_the_paper_preset() -> None:
    env = gym.make(ENV_ID, **SMALL)
    assert env.unwrapped.scenario == Scenario.paper()  # type: ignore[attr-defined]
    assert env.action_space == spaces.MultiDiscrete([5] * 6)


# Spaces and observations.


def test_spaces_for_the_paper_preset(paper: Scenario) -> None:
    env = SequenceSearchEnv(paper, seed=0, **SMALL)
    assert env.action_space == spaces.MultiDiscrete([5] * 6)
    assert env.observation_space == spaces.MultiDiscrete([6] * (3 * 6))


def test_spaces_follow_the_thrusters_and_levels() -> None:
    scenario = preset(
        "paper",
        thrusters={"torque_matrix_nm": np.diag([2.0, 2.0, 2.0]).tolist(), "levels": [0.0, 1.0]},
    )
    env = SequenceSearchEnv(scenario, sequence_length=2, n_realisations=2, seed=0)
    assert env.action_space == spaces.MultiDiscrete([2] * 3)
    assert env.observation_space == spaces.MultiDiscrete([3] * (2 * 3))


def test_observation_is_the_actuation_history_with_unused_steps_at_m(paper: Scenario) -> None:
    env = SequenceSearchEnv(paper, seed=0, **SMALL)
    obs, info = env.reset(seed=0)
    assert info == {}
    np.testing.assert_array_equal(obs, np.full(18, 5))
    for k, row in enumerate(MIXED_SEQUENCE, start=1):
        obs, *_ = env.step(np.asarray(row))
        assert env.observation_space.contains(obs)
        rows = obs.reshape(3, 6)
        np.testing.assert_array_equal(rows[:k], MIXED_SEQUENCE[:k])
        np.testing.assert_array_equal(rows[k:], 5)
    obs, _ = env.reset()
    np.testing.assert_array_equal(obs, np.full(18, 5))


# Episodes.


def test_episode_lasts_exactly_the_sequence_length(paper: Scenario) -> None:
    env = SequenceSearchEnv(paper, seed=0, **SMALL)
    env.reset(seed=0)
    flags = [env.step(np.asarray(row))[2:4] for row in MIXED_SEQUENCE]
    assert flags == [(False, False), (False, False), (True, False)]
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.asarray(MIXED_SEQUENCE[0]))
    env.reset()
    _, _, terminated, _, info = env.step(np.asarray(MIXED_SEQUENCE[0]))
    assert not terminated and info["step"] == 1


# The reward.


def test_rewards_follow_the_documented_formula(paper: Scenario) -> None:
    settings = ScorerSettings(n_realisations=5)
    env = SequenceSearchEnv(paper, sequence_length=3, seed=7, settings=settings)
    rewards, infos = play(env, MIXED_SEQUENCE)

    # Before the last step: -1 + 3 F1, F1 as an independent scorer on the same seed sees it.
    scorer = PrefixScorer(paper, 3, settings, seed=7)
    for k in (1, 2):
        f1 = scorer.score(MIXED_SEQUENCE[:k]).f1
        assert infos[k - 1]["f1"] == f1
        assert rewards[k - 1] == pytest.approx(-1.0 + 3.0 * f1, abs=1e-12)
        assert infos[k - 1]["step"] == k
        assert infos[k - 1]["sequence"] == MIXED_SEQUENCE[:k]

    # Last step: minus the mean true final rate over candidates and realisations, as the
    # simulator gives it for the same noise.
    simulated = Simulator(paper, 5).run(np.asarray(MIXED_SEQUENCE), env.scorer.noise)
    final_rate = float(np.linalg.norm(simulated.omega_true[:, :, -1, :], axis=-1).mean())
    assert infos[-1]["final_rate_rad_s"] == pytest.approx(final_rate, rel=1e-12)
    assert rewards[-1] == pytest.approx(-final_rate, rel=1e-12)
    assert 0.0 < final_rate < 1.0


def test_fuel_weight_charges_each_step_its_impulse(paper: Scenario) -> None:
    weight = 0.1
    free, free_infos = play(SequenceSearchEnv(paper, seed=7, **SMALL), MIXED_SEQUENCE)
    charged, infos = play(
        SequenceSearchEnv(paper, seed=7, fuel_weight=weight, **SMALL), MIXED_SEQUENCE
    )
    for k, impulse in enumerate(MIXED_STEP_IMPULSE_NMS):
        assert infos[k]["step_fuel_nms"] == pytest.approx(impulse, rel=1e-12)
        assert charged[k] == pytest.approx(free[k] - weight * impulse, abs=1e-12)
        assert infos[k]["f1"] == free_infos[k]["f1"]  # the fuel weight changes no score
    assert infos[-1]["fuel_nms"] == pytest.approx(sum(MIXED_STEP_IMPULSE_NMS), rel=1e-12)
    assert infos[-1]["fuel_nms"] == pytest.approx(paper.impulse_nms(MIXED_SEQUENCE), rel=1e-12)


def test_noise_free_good_sequence_separates_every_candidate_at_every_step(
    quiet_paper: Scenario, good_sequence: np.ndarray
) -> None:
    # Without noise every realisation of a candidate is the same series, and the good
    # sequence drives the candidates apart from the first step: F1 = 1, reward -1 + 3 = 2.
    env = SequenceSearchEnv(quiet_paper, sequence_length=4, n_realisations=5, seed=0)
    rewards, infos = play(env, good_sequence)
    assert [info["f1"] for info in infos] == [1.0] * 4
    assert rewards[:3] == [2.0, 2.0, 2.0]
    assert rewards[3] == -infos[3]["final_rate_rad_s"] < 0.0
    # Nothing random: another seed and another number of realisations change nothing.
    other = SequenceSearchEnv(quiet_paper, sequence_length=4, n_realisations=3, seed=1)
    assert play(other, good_sequence)[0] == pytest.approx(rewards, rel=1e-12)


@pytest.mark.parametrize(
    ("sequence", "seconds_on"), [([[1, 0, 0], [0, 0, 0]], 1), ([[1, 0, 0]] * 2, 2)]
)
def test_final_rate_of_a_spin_about_a_principal_axis_is_closed_form(
    zero_uncertainty: dict[str, Any], sequence: list[list[int]], seconds_on: int
) -> None:
    # One thruster torquing the body x axis (2 N m), no noise, no lag, diagonal inertia
    # tensors: ω stays on x, ω_x = 2 N m * t / I_xx, and coasting keeps it (Euler's
    # equations have no gyroscopic term for a spin about a principal axis).
    scenario = preset(
        "paper",
        thrusters={"torque_matrix_nm": np.diag([2.0, 2.0, 2.0]).tolist(), "levels": [0.0, 1.0]},
        uncertainty=zero_uncertainty,
    )
    env = SequenceSearchEnv(scenario, sequence_length=2, n_realisations=2, seed=0)
    rewards, infos = play(env, sequence)
    i_xx = scenario.inertia_array[:, 0, 0]
    expected = float(np.mean(2.0 * seconds_on / i_xx))
    assert infos[-1]["final_rate_rad_s"] == pytest.approx(expected, rel=1e-12)
    assert rewards[-1] == pytest.approx(-expected, rel=1e-12)


def test_noise_free_step_with_thrusters_off_scores(quiet_paper: Scenario) -> None:
    env = SequenceSearchEnv(quiet_paper, sequence_length=2, n_realisations=3, seed=0)
    env.reset()
    _, reward, *_ = env.step(np.zeros(6, dtype=int))
    # All candidates respond identically (not at all): one cluster holds everything.
    assert reward < 2.0


# Seeds and noise.


def test_same_seed_same_episode(paper: Scenario) -> None:
    first = play(SequenceSearchEnv(paper, seed=11, **SMALL), MIXED_SEQUENCE)
    second = play(SequenceSearchEnv(paper, seed=11, **SMALL), MIXED_SEQUENCE)
    assert first == second


def test_different_seeds_draw_different_noise(paper: Scenario) -> None:
    _, first = play(SequenceSearchEnv(paper, seed=11, **SMALL), MIXED_SEQUENCE)
    _, second = play(SequenceSearchEnv(paper, seed=12, **SMALL), MIXED_SEQUENCE)
    assert first[-1]["final_rate_rad_s"] != second[-1]["final_rate_rad_s"]


def test_reset_with_a_seed_redraws_the_noise_from_it(paper: Scenario) -> None:
    env = SequenceSearchEnv(paper, seed=0, **SMALL)
    before = play(env, MIXED_SEQUENCE)
    reseeded = play(env, MIXED_SEQUENCE, seed=5)
    assert reseeded != before
    assert reseeded == play(SequenceSearchEnv(paper, seed=5, **SMALL), MIXED_SEQUENCE)
    assert play(env, MIXED_SEQUENCE, seed=0) == before


def test_fixed_noise_scores_a_sequence_the_same_every_episode(paper: Scenario) -> None:
    env = SequenceSearchEnv(paper, seed=3, noise="fixed", **SMALL)
    first = play(env, MIXED_SEQUENCE, seed=3)
    assert play(env, MIXED_SEQUENCE) == first
    assert play(env, MIXED_SEQUENCE) == first


def test_fresh_noise_redraws_every_episode_reproducibly(paper: Scenario) -> None:
    def episodes() -> list[float]:
        env = SequenceSearchEnv(paper, seed=3, noise="fresh", **SMALL)
        rates = [play(env, MIXED_SEQUENCE, seed=3)[1][-1]["final_rate_rad_s"]]
        rates += [play(env, MIXED_SEQUENCE)[1][-1]["final_rate_rad_s"] for _ in range(2)]
        return rates

    rates = episodes()
    assert len(set(rates)) == 3
    assert episodes() == rates


def test_fresh_noise_is_reproducible_from_the_constructor_seed(paper: Scenario) -> None:
    def second_episode() -> float:
        env = SequenceSearchEnv(paper, seed=3, noise="fresh", **SMALL)
        play(env, MIXED_SEQUENCE)
        return play(env, MIXED_SEQUENCE)[1][-1]["final_rate_rad_s"]

    assert second_episode() == second_episode()


# Refusals.


@pytest.mark.parametrize(
    ("action", "quoted"),
    [
        ([4, 4, 4, 0, 0], "[4, 4, 4, 0, 0]"),
        ([4, 4, 4, 0, 0, 0, 0], "[4, 4, 4, 0, 0, 0, 0]"),
        ([5, 0, 0, 0, 0, 0], "[5, 0, 0, 0, 0, 0]"),
        ([-1, 0, 0, 0, 0, 0], "[-1, 0, 0, 0, 0, 0]"),
        ([1.5, 0, 0, 0, 0, 0], "[1.5, 0.0, 0.0, 0.0, 0.0, 0.0]"),
    ],
)
def test_invalid_action_is_refused_and_leaves_the_episode_as_it_was(
    paper: Scenario, action: list[float], quoted: str
) -> None:
    env = SequenceSearchEnv(paper, seed=0, **SMALL)
    env.reset()
    with pytest.raises(ValueError, match=re.escape(quoted)):
        env.step(np.asarray(action))
    _, _, _, _, info = env.step(np.asarray(MIXED_SEQUENCE[0]))
    assert info["step"] == 1


@pytest.mark.parametrize(
    ("kwargs", "quoted"),
    [
        ({"fuel_weight": -1.0}, "-1.0"),
        ({"fuel_weight": float("nan")}, "nan"),
        ({"noise": "x"}, "'x'"),
        ({"metric": "cosine"}, "'cosine'"),
        ({"n_realisations": 0}, "0"),
        ({"sequence_length": 0}, "0"),
    ],
)
def test_bad_constructor_arguments_are_refused(
    paper: Scenario, kwargs: dict[str, Any], quoted: str
) -> None:
    options = {**SMALL, **kwargs}
    with pytest.raises(ValueError, match=re.escape(quoted)):
        SequenceSearchEnv(paper, seed=0, **options)


def test_a_per_flight_bound_on_few_flights_a_candidate_is_refused(paper: Scenario) -> None:
    for n, factor in ((1, "inf"), (5, "4.2")):
        with pytest.raises(InputError, match=rf"needs n_realisations >= 10 .*got {n} .*{factor}"):
            SequenceSearchEnv(
                paper, n_realisations=n, seed=0, constraints={"max_final_rate_p95_rad_s": 0.01}
            )


def test_settings_and_their_keywords_together_are_refused(paper: Scenario) -> None:
    with pytest.raises(ValueError, match="not both"):
        SequenceSearchEnv(paper, settings=ScorerSettings(n_realisations=2), n_realisations=3)


@pytest.mark.parametrize(
    "name",
    [
        "max_final_rate_rad_s",
        "max_final_rate_deg_s",
        "max_final_rate_p95_rad_s",
        "max_final_rate_p95_deg_s",
    ],
)
def test_a_residual_rate_bound_is_checked_on_the_worst_candidates_settled_rate(
    paper: Scenario, name: str
) -> None:
    """Every constraint an environment accepts is scored at the last step (none may be
    missing from its figures); the residual-rate bound reads the settled rate of the
    candidate that ends fastest, as the Pareto search does."""
    from inertia_id.search.objectives import CONSTRAINTS

    brake = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]
    probe = SequenceSearchEnv(paper, sequence_length=2, n_realisations=10, seed=0)
    _, infos = play(probe, brake)
    figure, _, factor = CONSTRAINTS[name]
    # The mean or the rate 95 % of the flights stay under, of the candidate ending fastest
    worst = getattr(probe.scorer.score(tuple(map(tuple, brake))), figure)
    assert 0 < worst < infos[-1]["final_rate_rad_s"]  # settles below the end-of-step rate
    # The info's residual rate is the same settled figure, mean over the candidates.
    settled = probe.scorer.score(tuple(map(tuple, brake)))
    assert infos[-1]["residual_rate_rad_s"] == settled.residual_rate_rad_s
    assert 0 < settled.residual_rate_rad_s <= settled.final_rate_max_rad_s
    bound = 0.5 * worst / factor  # half the worst candidate's rate: violated by 1
    env = SequenceSearchEnv(
        paper, sequence_length=2, n_realisations=10, seed=0, constraints={name: bound}
    )
    _, infos = play(env, brake)
    assert infos[-1]["constraint_violation"] == pytest.approx(1.0)
    # Every constraint at once, each rate bounded in one unit (both at once is refused).
    for unit in ("rad_s", "deg_s"):
        others = {
            n: 1.0
            for n in CONSTRAINTS
            if n not in ("min_accuracy", "max_propellant_kg")
            and not (n.endswith(("_rad_s", "_deg_s")) and not n.endswith(unit))
        }
        assert len(others) == 9, others
        every = SequenceSearchEnv(
            paper, sequence_length=2, n_realisations=10, seed=0, constraints=others
        )
        _, infos = play(every, brake)
        assert np.isfinite(infos[-1]["constraint_violation"])


@pytest.mark.parametrize(
    ("name", "figure"),
    [
        ("max_commanded_residual_rate_deg_s", "commanded_residual_rate_rad_s"),
        ("max_commanded_residual_rate_rad_s", "commanded_residual_rate_rad_s"),
        ("max_commanded_residual_rate_max_deg_s", "commanded_residual_rate_max_rad_s"),
        ("max_commanded_residual_rate_max_rad_s", "commanded_residual_rate_max_rad_s"),
    ],
)
def test_a_commanded_residual_bound_is_checked_on_the_plans_prediction_from_rest(
    drifting_paper: Scenario, name: str, figure: str
) -> None:
    """With an initial-rate spread every flight keeps |ω(0)| (0.46 deg/s on average on
    paper-in-orbit), so a final-rate bound of 0.2 deg/s is refused and one above the
    floor tells a brake from an all-off sequence by nothing. A bound on the commanded
    residual (the plan's prediction from rest, every noise off) reads the part the
    commands leave: met by a brake, broken by a sequence that only fires. Before, the
    environment refused the name as an unknown constraint."""
    from inertia_id.search.objectives import CONSTRAINTS
    from inertia_id.search.plan import command_plan

    brake = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]
    spin = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 0, 0, 0]]
    plans = {
        "brake": command_plan(drifting_paper, brake).to_dict(),
        "spin": command_plan(drifting_paper, spin).to_dict(),
    }
    _, _, factor = CONSTRAINTS[name]
    bound = np.radians(0.2) / factor  # 0.2 deg/s in the constraint's unit
    env = SequenceSearchEnv(
        drifting_paper, sequence_length=2, n_realisations=10, seed=0, constraints={name: bound}
    )
    for label, sequence in (("brake", brake), ("spin", spin)):
        score = env.scorer.score(tuple(map(tuple, sequence)))
        # The scorer's figure is the command plan's, mean or worst candidate.
        rates = [c["commanded_residual_rate_rad_s"] for c in plans[label]["candidates"]]
        expected = max(rates) if figure.endswith("_max_rad_s") else float(np.mean(rates))
        assert getattr(score, figure) == pytest.approx(expected, rel=1e-9)
        _, infos = play(env, sequence)
        if label == "brake":
            assert getattr(score, figure) < np.radians(0.2)
            assert infos[-1]["constraint_violation"] == 0.0
            # Its total carries the floor: far above the bound.
            assert score.final_rate_max_rad_s > 2 * np.radians(0.2)
        else:
            violation = getattr(score, figure) / np.radians(0.2) - 1.0
            assert violation > 1.0
            assert infos[-1]["constraint_violation"] == pytest.approx(violation)


@pytest.mark.parametrize(
    "name", ["max_final_rate_rad_s", "max_final_rate_deg_s", "max_peak_rate_rad_s"]
)
def test_a_rate_bound_of_zero_costs_what_a_bound_just_above_zero_does(
    paper: Scenario, name: str
) -> None:
    """A bound of exactly 0 had no scale to divide by and the penalty fell back to the
    absolute excess (0.05 rad/s over cost 0.05 x constraint_penalty) while a bound of
    1e-9 rad/s cost 5e7 x: a violation is now measured against max(bound, the figure's
    stated scale), continuous in the bound, the Pareto search's ratios alike."""
    from inertia_id.search.objectives import CONSTRAINT_SCALES, CONSTRAINTS, SequenceScores

    spin = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 0, 0, 0]]
    figure, _, factor = CONSTRAINTS[name]
    scale = CONSTRAINT_SCALES[figure]
    violations = {}
    for bound_rad_s in (0.0, 1e-9, scale):
        env = SequenceSearchEnv(
            paper,
            sequence_length=2,
            n_realisations=4,
            seed=0,
            constraints={name: bound_rad_s / factor},
            constraint_penalty=2.0,
        )
        score = env.scorer.score(tuple(map(tuple, spin)))
        value = getattr(score, figure)
        assert value > 100 * scale  # the spin breaks every one of these bounds
        _, infos = play(env, spin)
        violations[bound_rad_s] = infos[-1]["constraint_violation"]
        assert violations[bound_rad_s] == pytest.approx((value - bound_rad_s) / scale)
        # NSGA-II reads the same ratio off a member's scores.
        member = SequenceScores(
            accuracy=1.0,
            accuracy_by_noise=[1.0],
            final_rate_rad_s=value,
            final_rate_max_rad_s=value,
            peak_rate_rad_s=value,
            impulse_nms=1.0,
            on_time_s=1.0,
            propellant_kg=None,
            duration_s=1.0,
            attitude_change_deg=0.0,
        )
        assert member.violations(env.constraints)[0] == pytest.approx(violations[bound_rad_s])
    assert violations[0.0] == pytest.approx(violations[1e-9], rel=1e-4)
    assert violations[0.0] > violations[scale] > 0.99 * violations[0.0]
