"""A scenario within every per-field bound whose noise overflows the simulated rates is
refused before anything runs (:mod:`inertia_id.physics.simulable`), naming the noise
figure, its value, the multiple and the step by which the rates overflow; one whose
rates are merely large is not."""

from __future__ import annotations

import numpy as np
import pytest

from inertia_id import Scenario, simulate
from inertia_id.errors import InputError
from inertia_id.evaluation.sweep import run_sweep
from inertia_id.physics.simulable import (
    CHECK_BUDGET,
    CHECK_REALISATIONS_MAX,
    CHECK_REALISATIONS_MIN,
    NoiseOverflow,
    check_realisations,
    check_scenario_simulable,
    check_simulable,
    overflow_step,
)
from inertia_id.physics.simulate import SimulationOverflow
from inertia_id.pipelines import SearchRequest, TrainRequest, check_search, train_for_sequence

SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4
FIELD = "disturbance_torque_sigma_nm"


@pytest.fixture(scope="module")
def overflowing() -> Scenario:
    """The paper preset at 1e4 N m: a hundredth of the bound, and its rates go to inf."""
    return Scenario.paper().with_uncertainty(**{FIELD: 1e4})


@pytest.fixture(scope="module")
def loud() -> Scenario:
    """The paper preset at 3e3 N m: large but finite rates at 1x on 4 steps."""
    return Scenario.paper().with_uncertainty(**{FIELD: 3e3})


def test_the_check_agrees_with_the_simulator_the_jobs_use(
    overflowing: Scenario, loud: Scenario
) -> None:
    with pytest.raises(SimulationOverflow):
        simulate(overflowing, SEQUENCE, 20, np.random.default_rng(0))
    assert overflow_step(overflowing, np.asarray(SEQUENCE)) == 2
    assert overflow_step(overflowing, np.asarray(SEQUENCE), n_realisations=8) == 3
    flown = simulate(loud, SEQUENCE, 20, np.random.default_rng(0))
    assert np.isfinite(flown.omega_measured).all() and np.abs(flown.omega_true).max() > 10.0
    assert overflow_step(loud, np.asarray(SEQUENCE)) is None
    # Large but finite for real jobs too: 210 realisations a candidate (training's
    # calibration) on a few seeds stay finite.
    for seed in range(1, 6):
        flown = simulate(loud, SEQUENCE, 210, np.random.default_rng(seed))
        assert np.isfinite(flown.omega_measured).all()


def test_the_check_flies_as_many_realisations_as_its_budget_allows() -> None:
    paper = Scenario.paper()  # 5 candidates, 20 RK4 steps a step
    assert check_realisations(paper, 4) == CHECK_REALISATIONS_MAX == 256
    assert check_realisations(paper, 64) == CHECK_BUDGET // (5 * 64 * 20) == 40
    assert check_realisations(paper, 10_000) == CHECK_REALISATIONS_MIN == 8


@pytest.mark.parametrize(
    ("field", "value", "shown"),
    [
        ("initial_rate_sigma_rad_s", 40.0, "initial_rate_sigma_rad_s = 40 rad/s"),
        ("disturbance_torque_sigma_nm", 7e3, "disturbance_torque_sigma_nm = 7000 N m"),
    ],
)
def test_a_noise_that_overflows_a_job_in_its_tail_is_refused(
    field: str, value: float, shown: str
) -> None:
    """Overflow is a tail event: 8 realisations a candidate flew through these, yet every
    job of 210 realisations a candidate (training's calibration) overflowed on them. The
    check flies 256 on the paper preset's 4 steps and refuses them."""
    noisy = Scenario.paper().with_uncertainty(**{field: value})
    assert overflow_step(noisy, np.asarray(SEQUENCE), n_realisations=8) is None
    for seed in (1, 2):
        with pytest.raises(SimulationOverflow):
            simulate(noisy, SEQUENCE, 210, np.random.default_rng(seed))
    with pytest.raises(NoiseOverflow) as refused:
        check_scenario_simulable(noisy)
    message = str(refused.value)
    assert f"{shown} at noise multiple 1 (the scenario's own)" in message
    assert "a seeded check of 256 realisations a candidate" in message
    assert refused.value.fields == (field,)


def test_a_scenario_that_overflows_at_its_own_noise_is_refused_naming_the_figure(
    overflowing: Scenario, loud: Scenario
) -> None:
    with pytest.raises(NoiseOverflow) as refused:
        check_scenario_simulable(overflowing)
    message = str(refused.value)
    assert f"{FIELD} = 10000 N m at noise multiple 1 (the scenario's own)" in message
    assert "inf or nan within 2 of the 4 steps" in message
    assert refused.value.fields == (FIELD,) and refused.value.multiple == 1.0
    assert isinstance(refused.value, InputError)
    check_scenario_simulable(loud)  # merely large: stored
    check_scenario_simulable(Scenario.paper())


def test_a_multiple_that_overflows_names_the_multiple_and_the_scaled_value(
    loud: Scenario,
) -> None:
    with pytest.raises(NoiseOverflow) as refused:
        check_simulable(loud, SEQUENCE, multiples={FIELD: 8})
    assert f"{FIELD} = 3000 N m at noise multiple 8 (24000 N m)" in str(refused.value)
    assert refused.value.multiple == 8.0
    # A sweep's reference level where the scenario states none (thrust scale).
    with pytest.raises(
        NoiseOverflow, match=r"thrust_scale_sigma = 0.02 at noise multiple 100000 \(2000\)"
    ):
        check_simulable(
            Scenario.paper(),
            SEQUENCE,
            multiples={"thrust_scale_sigma": 1e5},
            levels={"thrust_scale_sigma": 0.02},
        )


def test_training_refuses_before_its_first_draw(overflowing: Scenario) -> None:
    with pytest.raises(NoiseOverflow, match=f"{FIELD} = 10000 N m at noise multiple 1"):
        train_for_sequence(
            overflowing, TrainRequest(SEQUENCE, kind="nearest-centroid", metric="euclidean"), seed=0
        )


def test_a_search_refuses_at_1x_and_at_its_design_noise(
    overflowing: Scenario, loud: Scenario
) -> None:
    with pytest.raises(NoiseOverflow, match="no search on scenario 'paper' at 1x"):
        check_search(overflowing, SearchRequest(method="cem"))
    with pytest.raises(NoiseOverflow, match=r"at its design noise.*at noise multiple 6"):
        check_search(loud, SearchRequest(method="cem"))
    check_search(loud, SearchRequest(method="cem", design_noise=((1.0, 6.0),)))


def test_a_sweep_refuses_its_largest_multiple_before_its_first_point(loud: Scenario) -> None:
    from inertia_id import train_classifier

    classifier = train_classifier(
        loud, SEQUENCE, 5, np.random.default_rng(0), kind="nearest-centroid", metric="euclidean"
    )
    points: list[float] = []
    with pytest.raises(NoiseOverflow, match=r"process noise at multiple 8 \(24000 N m\)"):
        run_sweep(classifier, multiples=(1, 2, 8), n_test=10, progress=points.append)
    assert points == []  # refused before the first point was simulated
    run_sweep(classifier, multiples=(0.5, 1), n_test=10)


def test_a_scenario_spun_past_any_gyro_with_its_noise_off_is_left_to_the_sequence_rules() -> None:
    """Only the ratio of torque to inertia matters, so a scenario whose hand-designed
    sequence spins a body past any gyro with every noise off is stored (the plan's and the
    jobs' gyro-range rule refuses each such sequence, README "Scenario"): the storing check
    does not blame its noise for it. Nor does it fly hour-long steps (a job of them is
    checked, after its size, when it is submitted)."""
    document = Scenario.paper().model_dump(mode="json")
    document["inertia_candidates"][0]["inertia_kg_m2"] = (1e-30 * np.eye(3)).tolist()
    document["candidate_generator"] = None
    tiny = Scenario.model_validate(document)
    check_scenario_simulable(tiny)
    hourly = Scenario.model_validate(
        {**Scenario.paper().model_dump(mode="json"), "timing": {"step_duration_s": 3600.0}}
    )
    check_scenario_simulable(hourly.with_uncertainty(**{FIELD: 1e4}))
