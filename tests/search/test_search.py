"""Exhaustive, random and PPO search: what they return, when they stop, and that they agree."""

from __future__ import annotations

import importlib
import itertools
import json
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from stable_baselines3 import PPO

from inertia_id import Scenario, preset
from inertia_id.errors import InputError
from inertia_id.search import (
    PPO_DEFAULTS,
    ScorerSettings,
    SearchProgress,
    SearchResult,
    SequenceSearchEnv,
    check_ppo_params,
    exhaustive_search,
    ppo_search,
    random_search,
    search,
)
from inertia_id.search.firings import OpposedFirings

SETTINGS = ScorerSettings(n_realisations=4)
TINY_PPO = {"n_steps": 32, "batch_size": 16, "n_epochs": 2}


@pytest.fixture(scope="module")
def ppo_run(tiny: Scenario, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One tiny PPO search, with its progress reports and saved policy."""
    reports: list[SearchProgress] = []
    result = ppo_search(
        tiny,
        sequence_length=2,
        total_timesteps=96,
        seed=0,
        settings=SETTINGS,
        ppo_params=TINY_PPO,
        n_fresh_draws=1,
        policy_path=tmp_path_factory.mktemp("ppo") / "policy",
        progress=reports.append,
    )
    return {"result": result, "reports": reports}


def finished_episodes(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Record the info of every episode's last step that any environment plays."""
    infos: list[dict[str, Any]] = []
    original = SequenceSearchEnv.step

    def step(self: SequenceSearchEnv, action: Any) -> Any:
        out = original(self, action)
        if out[2]:
            infos.append(out[4])
        return out

    monkeypatch.setattr(SequenceSearchEnv, "step", step)
    return infos


def assert_json_clean(result: SearchResult) -> dict[str, Any]:
    def refuse(token: str) -> None:
        raise AssertionError(f"non-finite {token} in the JSON")

    data = json.loads(result.to_json(), parse_constant=refuse)
    assert data["method"] == result.method
    assert data["best"]["sequence"] == result.best.sequence
    assert data["fresh"]["f1_mean"] == pytest.approx(result.fresh.f1_mean)
    return data


# Exhaustive search.


@pytest.mark.parametrize("scenario_name", ["tiny", "tiny_quiet"])
def test_exhaustive_search_finds_the_brute_force_best(
    scenario_name: str, request: pytest.FixtureRequest
) -> None:
    # Noisy, the best F1 is unique; almost noise-free, many sequences reach F1 = 1 and the
    # final rate decides.
    tiny: Scenario = request.getfixturevalue(scenario_name)
    rows = list(itertools.product(range(2), repeat=3))
    env = SequenceSearchEnv(tiny, sequence_length=2, seed=3, settings=SETTINGS)
    played = []
    for sequence in itertools.product(rows, repeat=2):
        env.reset()
        for row in sequence:
            *_, info = env.step(np.asarray(row))
        played.append(([list(r) for r in sequence], info["f1"], info["final_rate_rad_s"]))
    # Highest F1, then lowest final rate; the first such in enumeration order.
    expected = max(played, key=lambda p: (p[1], -p[2]))
    assert sum(p[1] == expected[1] for p in played) < len(played)  # F1 tells them apart
    assert expected[0] != played[0][0]

    result = exhaustive_search(tiny, sequence_length=2, seed=3, settings=SETTINGS, n_fresh_draws=2)
    assert result.best.sequence == expected[0]
    assert result.best.f1 == expected[1]
    assert result.best.final_rate_rad_s == expected[2]
    assert result.best.fuel_nms == pytest.approx(tiny.impulse_nms(expected[0]), rel=1e-12)
    assert (result.episodes, result.timesteps, result.space_size) == (64, 128, 64)
    assert result.stopped == "exhausted"
    assert result.method == "exhaustive"
    assert len(result.fresh.f1) == 2


def test_exhaustive_search_refuses_a_large_space_before_any_work(
    paper: Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    module = importlib.import_module("inertia_id.search.exhaustive")

    def no_env(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("an environment was built for a refused space")

    monkeypatch.setattr(module, "SearchRun", no_env)
    with pytest.raises(ValueError, match=re.escape("(5^6)^2")):
        exhaustive_search(paper, sequence_length=2)


def test_exhaustive_search_budget_is_the_largest_space_it_enumerates(tiny: Scenario) -> None:
    with pytest.raises(ValueError, match=re.escape("(2^3)^2 = 64")):
        exhaustive_search(tiny, sequence_length=2, max_sequences=63, settings=SETTINGS)
    with pytest.raises(ValueError, match="max_sequences"):
        exhaustive_search(tiny, sequence_length=2, max_sequences=0, settings=SETTINGS)


# Random search.


def test_random_search_reports_what_it_played(
    tiny: Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    episodes = finished_episodes(monkeypatch)
    reports: list[SearchProgress] = []
    result = random_search(
        tiny,
        sequence_length=2,
        total_timesteps=41,
        seed=1,
        settings=SETTINGS,
        report_every=8,
        n_fresh_draws=3,
        progress=reports.append,
    )
    assert result.method == "random"
    assert result.stopped == "budget"
    assert (result.timesteps, result.episodes) == (40, 20)  # whole sequences within 41 steps
    assert len(episodes) == result.episodes

    best_f1 = max(info["f1"] for info in episodes)
    assert result.best.f1 == best_f1
    assert result.best.final_rate_rad_s == min(
        info["final_rate_rad_s"] for info in episodes if info["f1"] == best_f1
    )
    assert result.best.sequence in [info["sequence"] for info in episodes]

    assert [p.timesteps for p in result.curve] == [8, 16, 24, 32, 40]
    assert [p.best_f1 for p in result.curve] == sorted(p.best_f1 for p in result.curve)
    assert result.curve[-1].best_f1 == result.best.f1
    # The curve's rate is the residual once the lag is empty, the front's figure, not
    # the end-of-command rate the reward reads (which it settles below).
    best_info = next(i for i in episodes if i["sequence"] == result.best.sequence)
    assert result.best.residual_rate_rad_s == best_info["residual_rate_rad_s"]
    assert result.curve[-1].best_residual_rate_rad_s == result.best.residual_rate_rad_s
    assert 0 < result.best.residual_rate_rad_s != result.best.final_rate_rad_s
    assert [r.point for r in reports] == result.curve
    assert [r.fraction for r in reports] == pytest.approx(
        [8 / 41, 16 / 41, 24 / 41, 32 / 41, 40 / 41]
    )
    # The summary names each rate for what it is, in rad/s and deg/s.
    summary = result.summary()
    residual, end = result.best.residual_rate_rad_s, np.mean(result.fresh.final_rate_rad_s)
    assert f"residual rate {residual:.4f} rad/s ({math.degrees(residual):.3f} deg/s)" in summary
    assert f"|ω| at the last step's end {end:.4f} rad/s ({math.degrees(end):.3f}" in summary
    assert "final rate" not in summary and "fuel" not in summary

    assert result.fresh.seed != 1 and len(result.fresh.f1) == 3
    assert all(0.0 <= f1 <= 1.0 for f1 in result.fresh.f1)
    assert_json_clean(result)


def test_random_search_is_reproducible(tiny: Scenario) -> None:
    def run(seed: int) -> SearchResult:
        return random_search(
            tiny, sequence_length=2, total_timesteps=20, seed=seed, settings=SETTINGS,
            n_fresh_draws=1,
        )  # fmt: skip

    first, second = run(4), run(4)
    assert first.best == second.best and first.curve == second.curve
    assert run(5).curve != first.curve


def test_random_search_stops_at_the_target(tiny_quiet: Scenario) -> None:
    result = random_search(
        tiny_quiet,
        sequence_length=2,
        total_timesteps=400,
        seed=0,
        settings=ScorerSettings(n_realisations=3),
        patience_episodes=5,
        n_fresh_draws=1,
    )
    assert result.stopped == "target"
    assert result.timesteps < 400
    assert result.best.f1 == 1.0
    # It stopped as soon as five episodes in a row brought nothing better.
    assert result.episodes == result.best.episode + 5


def test_random_search_cancel_is_checked_before_each_sequence(
    tiny: Scenario, stop_after: Callable[[int], Any]
) -> None:
    should_stop = stop_after(3)
    result = random_search(
        tiny, sequence_length=2, total_timesteps=100, settings=SETTINGS, n_fresh_draws=1,
        should_stop=should_stop,
    )  # fmt: skip
    assert result.stopped == "cancelled"
    assert (result.episodes, result.timesteps) == (3, 6)


def test_budget_shorter_than_a_sequence_is_refused(tiny: Scenario) -> None:
    with pytest.raises(ValueError, match="got 1"):
        random_search(tiny, sequence_length=2, total_timesteps=1, settings=SETTINGS)
    with pytest.raises(ValueError, match="got 1"):
        ppo_search(tiny, sequence_length=2, total_timesteps=1, settings=SETTINGS)


def test_unknown_search_method_is_refused(tiny: Scenario) -> None:
    with pytest.raises(ValueError, match="'annealing'"):
        search("annealing", tiny)


# PPO search.


def test_ppo_result_has_the_shape_of_every_search(ppo_run: dict[str, Any], tiny: Scenario) -> None:
    result: SearchResult = ppo_run["result"]
    baseline = random_search(
        tiny, sequence_length=2, total_timesteps=8, settings=SETTINGS, n_fresh_draws=1
    )
    assert result.method == "ppo" and result.stopped == "budget"
    assert (result.timesteps, result.episodes, result.space_size) == (96, 48, 64)
    ppo_json, random_json = assert_json_clean(result), assert_json_clean(baseline)
    assert ppo_json.keys() == random_json.keys()
    assert ppo_json["best"].keys() == random_json["best"].keys()
    assert ppo_json["curve"][0].keys() == random_json["curve"][0].keys()
    assert ppo_json["settings"]["ppo"] == {**PPO_DEFAULTS, **TINY_PPO}


def test_ppo_progress_is_reported_after_every_rollout(ppo_run: dict[str, Any]) -> None:
    result: SearchResult = ppo_run["result"]
    reports: list[SearchProgress] = ppo_run["reports"]
    assert [r.timesteps for r in reports] == [32, 64, 96]
    assert [r.episodes for r in reports] == [16, 32, 48]  # 2-step episodes
    assert [r.fraction for r in reports] == pytest.approx([1 / 3, 2 / 3, 1.0])
    assert [r.point for r in reports] == result.curve
    assert all(r.best is not None for r in reports)
    assert reports[-1].best == result.best


def test_ppo_saves_a_policy_stable_baselines3_can_load(
    ppo_run: dict[str, Any], tiny: Scenario
) -> None:
    result: SearchResult = ppo_run["result"]
    assert result.policy_path is not None and result.policy_path.endswith("policy.zip")
    assert Path(result.policy_path).is_file()
    model = PPO.load(result.policy_path, device="cpu")
    env = SequenceSearchEnv(tiny, sequence_length=2, settings=SETTINGS, seed=0)
    obs, _ = env.reset()
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(np.asarray(action))


def test_ppo_same_seed_same_learning_curve(ppo_run: dict[str, Any], tiny: Scenario) -> None:
    def run(seed: int) -> SearchResult:
        return ppo_search(
            tiny, sequence_length=2, total_timesteps=96, seed=seed, settings=SETTINGS,
            ppo_params=TINY_PPO, n_fresh_draws=1,
        )  # fmt: skip

    first: SearchResult = ppo_run["result"]
    again = run(0)
    assert again.curve == first.curve
    assert again.best == first.best
    assert again.fresh == first.fresh
    assert run(1).curve != first.curve


def test_ppo_cancel_stops_at_the_next_step(
    tiny: Scenario, stop_after: Callable[[int], Any]
) -> None:
    # PPO checks before every step: the 40th check cancels it.
    should_stop = stop_after(39)
    result = ppo_search(
        tiny, sequence_length=2, total_timesteps=320, settings=SETTINGS, ppo_params=TINY_PPO,
        n_fresh_draws=1, should_stop=should_stop,
    )  # fmt: skip
    assert result.stopped == "cancelled"
    assert result.timesteps <= 40 + 32  # within the rollout it was cancelled in
    assert result.timesteps == 40  # in fact at the very step (polled every step)
    assert result.curve[-1].timesteps == 40


def test_ppo_leaves_no_log_folder_in_the_temporary_directory(
    tiny: Scenario, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # stable-baselines3 made an empty SB3-<date> folder in the temporary directory for
    # every learn() without a logger of ours (verbose 0 logs nowhere, but its logger is
    # still given a folder): a serve accumulated one for each PPO search it ran (44 in
    # /tmp after one CI run).
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    ppo_search(
        tiny, sequence_length=2, total_timesteps=16, settings=SETTINGS, ppo_params=TINY_PPO,
        n_fresh_draws=1,
    )  # fmt: skip
    # torch may make its per-user compile cache there (torchinductor_<user>, one folder
    # reused by every process, made by the first search in a process): not ours to judge.
    left = sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("torchinductor_"))
    assert left == []


def test_ppo_curve_point_before_any_episode_is_null_in_json(tiny: Scenario) -> None:
    # Two-step rollouts of three-step episodes: the first rollout ends mid-episode.
    result = ppo_search(
        tiny, sequence_length=3, total_timesteps=6, settings=SETTINGS,
        ppo_params={"n_steps": 2, "batch_size": 2, "n_epochs": 1}, n_fresh_draws=1,
    )  # fmt: skip
    assert [p.timesteps for p in result.curve] == [2, 4, 6]
    assert math.isnan(result.curve[0].mean_episode_reward)
    data = assert_json_clean(result)
    assert data["curve"][0]["mean_episode_reward"] is None
    assert data["curve"][1]["mean_episode_reward"] == result.curve[1].mean_episode_reward


# PPO parameters.


def test_ppo_parameters_default_to_the_papers() -> None:
    assert check_ppo_params(None) == {
        "n_steps": 2048,
        "learning_rate": 3e-4,
        "batch_size": 64,
        "n_epochs": 10,
        "gamma": 0.99,
        "gae_lambda": 0.95,
        "clip_range": 0.2,
        "ent_coef": 0.05,
        "vf_coef": 0.5,
        "max_grad_norm": 0.5,
    }
    merged = check_ppo_params({"n_steps": 64.0, "gamma": 0.9})
    assert merged["n_steps"] == 64 and isinstance(merged["n_steps"], int)
    assert merged["gamma"] == 0.9 and merged["batch_size"] == 64


def test_unknown_ppo_parameters_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match=re.escape("['lr', 'seed']")):
        check_ppo_params({"lr": 1e-3, "seed": 0, "gamma": 0.9})


def test_ppo_parameters_that_pass_the_check_train(tiny: Scenario) -> None:
    params = {"n_steps": 2, "batch_size": 2, "n_epochs": 1}
    check_ppo_params(params)
    ppo_search(
        tiny, sequence_length=2, total_timesteps=2, settings=SETTINGS, ppo_params=params,
        n_fresh_draws=1,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("params", "named"),
    [
        ({"n_steps": 0}, "n_steps"),
        ({"n_steps": 10.5}, "n_steps"),
        ({"n_epochs": True}, "n_epochs"),
        ({"batch_size": "64"}, "batch_size"),
        ({"gamma": 1.5}, "gamma"),
        ({"gae_lambda": -0.1}, "gae_lambda"),
        ({"learning_rate": 0.0}, "learning_rate"),
        ({"clip_range": -0.2}, "clip_range"),
        ({"ent_coef": -0.01}, "ent_coef"),
        ({"vf_coef": float("nan")}, "vf_coef"),
        ({"n_steps": 32, "batch_size": 64}, "batch_size"),
        ({"n_steps": 2, "batch_size": 1}, "batch_size must be at least 2"),
    ],
)
def test_bad_ppo_parameters_are_refused_by_name(params: dict[str, Any], named: str) -> None:
    with pytest.raises(ValueError, match=named):
        check_ppo_params(params)


@pytest.mark.parametrize("value", [10**400, float("inf"), 10**8])
def test_ppo_sizes_beyond_any_machine_are_refused(value: float) -> None:
    with pytest.raises(ValueError, match="n_steps must be at most 1e"):
        check_ppo_params({"n_steps": value})


def test_exhaustive_refuses_a_space_beyond_float_range_by_its_magnitude() -> None:
    huge = preset("paper", thrusters={"n_levels": 101, "nominal_torque_nm": 2.0})
    with pytest.raises(ValueError, match=r"\(101\^6\)\^100 = about 10\^1202 sequences"):
        exhaustive_search(huge, sequence_length=100)


def test_a_trackers_curve_says_whether_its_best_met_the_constraints() -> None:
    # The other methods rank a sequence that breaks the constraints below any that meets
    # them; until one does, the best so far breaks them, and its curve point says so.
    from inertia_id.search.records import SearchTracker

    tracker = SearchTracker()

    def episode(f1: float, violation: float) -> None:
        info = {
            "sequence": [[4, 0, 0, 0, 0, 0]],
            "f1": f1,
            "final_rate_rad_s": 0.1,
            "fuel_nms": 2.0,
            "constraint_violation": violation,
            "residual_rate_rad_s": 0.1,
        }
        tracker.on_step(0.0, True, info)

    episode(0.9, 0.5)
    assert tracker.add_point().best_feasible is False
    episode(0.6, 0.0)
    point = tracker.add_point()
    assert point.best_feasible is True and point.best_f1 == 0.6


@pytest.mark.parametrize("method", ["cem", "random"])
def test_a_best_found_with_cancelling_firings_has_them_taken_off(method: str) -> None:
    """CEM and random search sample each thruster's level apart, so their best fired
    opposing thrusters together: on the paper preset (separability, L = 3, 300 steps)
    all of seeds 0-2's bests did, up to 23.5 N m s where 10.5 gave the same torques.
    The best is now the same manoeuvre without them, and the result says what was
    taken off."""
    paper = preset("paper")
    result = search(
        method,
        paper,
        sequence_length=3,
        total_timesteps=300,
        seed=0,
        settings=ScorerSettings(n_realisations=4, objective="separability"),
        n_fresh_draws=1,
    )
    best = result.best_sequence
    assert OpposedFirings(paper)(best).tolist() == best.tolist()
    taken = result.firings_taken_off
    assert taken is not None
    found = np.asarray(taken["sequence_found"])
    assert not np.array_equal(found, best)
    duty, torque = paper.level_values, paper.torque_matrix
    assert np.allclose(duty[best] @ torque.T, duty[found] @ torque.T)
    assert taken["impulse_saved_nms"] == pytest.approx(
        taken["impulse_found_nms"] - result.best.fuel_nms
    )
    assert taken["impulse_saved_nms"] > 0
    assert taken["on_time_saved_s"] == pytest.approx(
        paper.on_time_s(found).sum() - paper.on_time_s(best).sum()
    )
    assert taken["steps"] == [k + 1 for k in range(3) if not np.array_equal(found[k], best[k])]
    assert "firings that cancelled taken off" in result.summary()
    assert json.loads(result.to_json())["firings_taken_off"]["sequence_found"] == found.tolist()
    from service.exports import result_table

    summary = dict(result_table("search", json.loads(result.to_json()), "summary").rows)
    assert summary["sequence_found"] == found.tolist()
    assert summary["impulse_saved_nms"] == taken["impulse_saved_nms"]


def test_a_search_whose_best_fires_nothing_says_so() -> None:
    """On four tetrahedral thrusters one step separates nothing at the separability
    objective's margin: all 81 sequences score 0.000, and the ties went to the all-off
    sequence (the smallest residual), returned as the best that ``train`` refuses. The
    search now says why no sequence that fires came first."""
    s = 1 / np.sqrt(3)
    tetra = preset(
        "paper",
        thrusters={
            "torque_matrix_nm": [[s, -s, -s, s], [s, -s, s, -s], [s, s, -s, -s]],
            "levels": [0.0, 0.5, 1.0],
        },
    )
    with pytest.raises(InputError, match=r"\[\[0, 0, 0, 0\]\], applies no torque") as refused:
        exhaustive_search(
            tetra,
            sequence_length=1,
            settings=ScorerSettings(n_realisations=4, objective="separability"),
            n_fresh_draws=1,
        )
    assert "(separability 0.000) in all 81 sequences of the space" in str(refused.value)
    assert "a smaller separability_margin" in str(refused.value)


def test_a_best_that_breaks_the_constraints_on_the_search_draw_says_so(tiny: Scenario) -> None:
    """A search other than NSGA-II keeps its best when no sequence it tried met the
    constraints (the least violating); its summary and the result's CSV summary said
    nothing of it (a hostile review: CEM, 4,000 steps, every curve point infeasible)."""
    from service.exports import result_table

    result = random_search(
        tiny,
        sequence_length=2,
        total_timesteps=8,
        seed=0,
        settings=SETTINGS,
        n_fresh_draws=1,
        constraints={"max_final_rate_rad_s": 1e-6},
    )
    violation = result.best.constraint_violation
    assert violation > 0
    assert (
        f"breaks the constraints on the search's draw (summed relative violation {violation:.3g})"
        in (result.summary())
    )
    summary = dict(result_table("search", json.loads(result.to_json()), "summary").rows)
    assert summary["best_meets_constraints_search_draw"] is False
    assert summary["best_constraint_violation_search_draw"] == violation
    # Without constraints there is nothing to meet: no row, no sentence.
    free = random_search(
        tiny, sequence_length=2, total_timesteps=8, seed=0, settings=SETTINGS, n_fresh_draws=1
    )
    free_summary = dict(result_table("search", json.loads(free.to_json()), "summary").rows)
    assert "best_meets_constraints_search_draw" not in free_summary
    assert "breaks the constraints" not in free.summary()
