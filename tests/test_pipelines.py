"""The use cases the CLI and the worker share: requests, defaults, seeding, refusals."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import (
    InertiaClassifier,
    InputError,
    LikelihoodClassifier,
    MarginalLikelihoodClassifier,
    Scenario,
    preset,
    run_inertia_sweep,
    run_sweep,
)
from inertia_id.classifiers.registry import train_classifier
from inertia_id.pipelines import (
    SearchRequest,
    SweepRequest,
    TrainRequest,
    check_sweep_scenario,
    run_paper,
    sweep_with_limit,
    train_for_sequence,
    train_others,
)

# Requests from job params.


def test_a_request_takes_the_names_it_knows_and_defaults_the_rest() -> None:
    request = SweepRequest.from_params({"classifier_id": "c1", "n_test": 50, "inertia": False})
    assert (request.n_test, request.inertia) == (50, False)
    assert request.ceiling_realisations == 2000 == SweepRequest.default("ceiling_realisations")
    assert request.limit_realisations is None  # the deprecated name: unset
    assert request.others == ("least-squares",)
    with pytest.raises(InputError, match=r"the job's params lack \['sequence'\]"):
        TrainRequest.from_params({"kind": "1nn"})


def test_a_train_request_resolves_kind_realisations_and_options() -> None:
    assert TrainRequest(GOOD_SEQUENCE).resolved() == ("marginal-likelihood", 100, {})
    assert TrainRequest(GOOD_SEQUENCE, metric="euclidean").resolved() == (
        "clustering",
        20,
        {"metric": "euclidean"},
    )
    assert TrainRequest(
        GOOD_SEQUENCE, kind="1nn", sakoe_chiba_radius=3, n_realisations=7
    ).resolved() == (
        "1nn",
        7,
        {"metric": "dtw", "sakoe_chiba_radius": 3},
    )
    with pytest.raises(InputError, match=r"the 'likelihood' classifier takes no metric, got 'dtw'"):
        TrainRequest(GOOD_SEQUENCE, kind="likelihood", metric="dtw").resolved()
    with pytest.raises(InputError, match=r"takes no DTW band, got 2"):
        TrainRequest(GOOD_SEQUENCE, kind="least-squares", sakoe_chiba_radius=2).resolved()
    # The band constrains dtw only; with euclidean or softdtw it was dropped silently.
    for kind, metric in (
        ("clustering", "euclidean"),
        ("clustering", "softdtw"),
        ("1nn", "euclidean"),
    ):
        with pytest.raises(InputError, match=rf"applies to metric 'dtw' only, not '{metric}'"):
            TrainRequest(GOOD_SEQUENCE, kind=kind, metric=metric, sakoe_chiba_radius=3).resolved()


def test_a_search_request_gives_each_method_its_own_options() -> None:
    ppo = SearchRequest(method="ppo", ppo={"n_steps": 64}).options()
    assert ppo["ppo_params"] == {"n_steps": 64} and ppo["total_timesteps"] == 20_480
    exhaustive = SearchRequest(method="exhaustive", sequence_length=1).options()
    assert exhaustive == {
        "sequence_length": 1,
        "fuel_weight": 0.0,
        "max_sequences": 100_000,
        "constraints": None,
        "constraint_penalty": 0.0,
        "time_limit_s": None,
        "time_limit_grace_s": None,
    }
    assert SearchRequest(method="cem", cem={"population": 8}).options()["population"] == 8
    with pytest.raises(InputError, match="ppo settings apply to method ppo only, not 'random'"):
        SearchRequest(method="random", ppo={"gamma": 0.9}).options()
    assert SearchRequest().scorer().sakoe_chiba_radius == 2


# Training.


def test_training_draws_from_the_seed(paper: Scenario) -> None:
    request = TrainRequest(GOOD_SEQUENCE, metric="euclidean", n_realisations=5)
    trained = train_for_sequence(paper, request, seed=3)
    assert isinstance(trained.model, InertiaClassifier)
    same = train_classifier(paper, GOOD_SEQUENCE, 5, np.random.default_rng(3), metric="euclidean")
    assert trained.model.to_json() == same.to_json()
    assert trained.summary()["n_realisations"] == 5 and trained.summary()["kind"] == "clustering"
    default = train_for_sequence(paper, TrainRequest(GOOD_SEQUENCE, n_realisations=4), seed=3)
    assert isinstance(default.model, MarginalLikelihoodClassifier)


@pytest.mark.parametrize("kind", ["marginal-likelihood", "likelihood", "clustering"])
def test_a_training_stops_at_the_checkpoint_after_it_is_asked_to(
    paper: Scenario, kind: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, train_for_sequence took no should_stop: a cancel, a worker's stop and a time
    # limit all waited for the whole training.
    from inertia_id.physics.simulate import Simulator
    from inertia_id.stopping import TrainingStopped

    runs: list[int] = []
    run = Simulator.run

    def counted(self: Simulator, *args: Any, **kwargs: Any) -> Any:
        runs.append(1)
        return run(self, *args, **kwargs)

    monkeypatch.setattr(Simulator, "run", counted)
    request = TrainRequest(GOOD_SEQUENCE, kind=kind, n_realisations=6)
    asked: list[int] = []

    def never() -> bool:
        asked.append(1)
        return False

    whole = train_for_sequence(paper, request, seed=5, should_stop=never)
    checkpoints, simulations = len(asked), len(runs)
    # Asked and never stopping, the training is the one trained without asking.
    assert whole.model.to_json() == train_for_sequence(paper, request, seed=5).model.to_json()
    asked.clear()
    runs.clear()

    def after_the_first() -> bool:
        asked.append(1)
        return len(asked) > 1

    with pytest.raises(TrainingStopped):
        train_for_sequence(paper, request, seed=5, should_stop=after_the_first)
    # Stopped at the second checkpoint, well before the whole training's last one, and
    # before the calibration's draws (the last simulation).
    assert len(asked) == 2
    assert checkpoints >= (40 if kind == "marginal-likelihood" else 4), checkpoints
    assert len(runs) < simulations, (len(runs), simulations)


def test_others_train_one_after_another_from_one_generator(paper: Scenario) -> None:
    others = train_others(
        paper, GOOD_SEQUENCE, ["likelihood", "1nn:euclidean"], 4, np.random.default_rng(2)
    )
    assert list(others) == ["likelihood", "1nn:euclidean"]
    assert isinstance(others["likelihood"], LikelihoodClassifier)
    assert others["1nn:euclidean"].metric == "euclidean"


def test_others_stop_before_the_next_and_at_a_training_checkpoint(paper: Scenario) -> None:
    calls: list[int] = []

    def at_call(n: int) -> Any:
        def should_stop() -> bool:
            calls.append(1)
            return len(calls) >= n

        return should_stop

    specs = ["likelihood", "1nn:euclidean"]
    rng = np.random.default_rng(2)
    assert train_others(paper, GOOD_SEQUENCE, specs, 4, rng, should_stop=at_call(1)) == {}
    # Asked before the likelihood (go on), then at its training's first checkpoint: stop.
    calls.clear()
    assert train_others(paper, GOOD_SEQUENCE, specs, 4, rng, should_stop=at_call(2)) == {}
    assert len(calls) == 2


def test_a_sweep_stopped_while_its_others_train_trains_no_more_and_measures_nothing(
    euclidean_classifier: InertiaClassifier, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sweep's stop (its job's time limit or cancel) was asked between points only, and
    every comparison classifier was trained before the first ask: a limit spent in their
    training was overrun by all of it. Now each is asked for first."""
    from inertia_id.classifiers import registry

    trained: list[str | None] = []
    real = registry.train_classifier

    def counted(*args: Any, **kwargs: Any) -> Any:
        model = real(*args, **kwargs)
        trained.append(kwargs.get("kind"))
        return model

    monkeypatch.setattr(registry, "train_classifier", counted)
    request = SweepRequest(
        multiples=(1, 6),
        others=("likelihood", "1nn:euclidean"),
        n_train=4,
        n_test=20,
        ceiling_realisations=0,
        inertia=False,
    )
    outcome = sweep_with_limit(
        euclidean_classifier, request, seed=3, should_stop=lambda: len(trained) >= 1
    )
    assert trained == ["likelihood"]
    assert outcome.sweep.points == []


# The sweep: one seeding scheme, and the scenario it names.


def test_the_sweep_seeds_its_streams_from_one_seed(
    euclidean_classifier: InertiaClassifier,
) -> None:
    request = SweepRequest(
        multiples=(1, 6), others=("likelihood",), n_train=4, n_test=20, ceiling_realisations=200
    )
    outcome = sweep_with_limit(euclidean_classifier, request, seed=9)
    streams = np.random.SeedSequence(9).spawn(3)
    test_seed = int(streams[1].generate_state(1)[0])
    assert outcome.sweep.seed == test_seed
    others = train_others(
        euclidean_classifier.scenario_,
        GOOD_SEQUENCE,
        ["likelihood"],
        4,
        np.random.default_rng(streams[0]),
    )
    by_hand = run_sweep(
        euclidean_classifier,
        others=others,
        multiples=(1, 6),
        n_test=20,
        ceiling_realisations=200,
        seed=test_seed,
    )
    assert outcome.sweep == by_hand
    inertia = run_inertia_sweep(euclidean_classifier, seed=int(streams[2].generate_state(1)[0]))
    assert outcome.inertia == inertia
    assert outcome.to_dict()["inertia"] == inertia.model_dump(mode="json")
    # The seed that runs it again, beside the derived ones (the test series' 4,053,640,108).
    assert outcome.run_seed == outcome.to_dict()["run_seed"] == 9


def test_a_sweep_runs_on_the_scenario_it_names(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    noisier = paper.with_uncertainty(gyro_noise_sigma_rad_s=3e-3)
    request = SweepRequest(multiples=(1,), others=(), limit_realisations=0, inertia=False)
    own = sweep_with_limit(euclidean_classifier, request, seed=1, scenario=paper)
    named = sweep_with_limit(euclidean_classifier, request, seed=1, scenario=noisier)
    assert named.sweep.levels["measurement"] == 3e-3 != own.sweep.levels["measurement"]


@pytest.mark.parametrize(
    "past", [{"duty_jitter_sigma": 20.0}, {"lowpass_time_constant_s": 150.0}], ids=str
)
def test_a_sweep_of_a_classifier_trained_past_todays_noise_bounds_runs_on_its_scenario(
    paper: Scenario, past: dict[str, float]
) -> None:
    # A classifier trained on a scenario past today's bounds on a stated figure loads
    # as trained (AS_TRAINED), and `inertia-id sweep` runs on its scenario by default.
    # Two rebuilt copies of it were validated as a new statement and refused the sweep:
    # the nominal (noise-off) one keeps the lag, "lowpass_time_constant_s = 150.0 s is
    # an actuation lag of 150 steps", and the bodies off the candidates keep the noise,
    # "duty_jitter_sigma = 20.0".
    noise = paper.uncertainty.model_copy(update=past)
    trained_on = paper.model_copy(update={"uncertainty": noise})  # as older code stored it
    model = train_classifier(
        trained_on, GOOD_SEQUENCE, 5, np.random.default_rng(0), kind="likelihood"
    )
    loaded = type(model).from_json(model.to_json())
    request = SweepRequest(multiples=(1,), others=(), ceiling_realisations=0, n_test=5)
    outcome = sweep_with_limit(loaded, request, seed=1)
    assert outcome.inertia is not None and outcome.sweep.points


def test_a_sweep_refuses_a_scenario_with_other_candidates(
    euclidean_classifier: InertiaClassifier, paper: Scenario, scenario_like: type
) -> None:
    other = scenario_like({"a": np.diag([10.0, 11.0, 12.0]), "b": np.diag([20.0, 21.0, 22.0])})
    request = SweepRequest(multiples=(1,), inertia=False)
    with pytest.raises(InputError, match=r"has candidates \['a', 'b'\], not the ones"):
        sweep_with_limit(euclidean_classifier, request, seed=1, scenario=other)
    slower = preset("paper", timing={"sample_rate_hz": 10.0})
    with pytest.raises(InputError, match=r"samples 10 times per step at 10 Hz; the classifier"):
        check_sweep_scenario(slower, paper, GOOD_SEQUENCE)
    fewer = preset("paper", thrusters={"n_levels": 3})
    with pytest.raises(InputError, match=r"does not drive scenario 'paper': .* level index 4"):
        check_sweep_scenario(fewer, paper, GOOD_SEQUENCE)


# The paper.


def test_the_paper_pipeline_keeps_its_seeds(tmp_path: Path) -> None:
    """Training from the first spawned stream, the sweep's test draws from the seed's
    own sweep streams: the figures the README quotes."""
    outcome = run_paper(
        tmp_path, metric="euclidean", n_realisations=5, multiples=(1, 8), n_test=20, seed=2
    )
    streams = np.random.SeedSequence(2).spawn(3)
    assert outcome.sweep.seed == int(streams[1].generate_state(1)[0])
    classifier = InertiaClassifier.load(tmp_path / "classifier.json")
    again = train_classifier(
        Scenario.paper(), GOOD_SEQUENCE, 5, np.random.default_rng(streams[0]), metric="euclidean"
    )
    assert classifier.to_json() == again.to_json()
    assert outcome.summary["sequence_from"] == "given" and outcome.summary["seed"] == 2
    assert json.loads((tmp_path / "sweep.json").read_text())["run_seed"] == 2
    assert set(outcome.sweep.others) == {"least-squares"} and outcome.sweep.limit
    assert not (tmp_path / "search.json").exists()


def test_a_cancel_during_the_front_measurement_of_another_method_keeps_the_prediction(
    paper: Scenario,
) -> None:
    """After a CEM, PPO, random or exhaustive search, its one-sequence front is measured
    too; a cancel that arrives then is heard, and the front says its accuracy is
    predicted (as NSGA-II's does)."""
    from inertia_id.pipelines import search_with_baselines

    request = SearchRequest(
        method="random", sequence_length=2, timesteps=8, n_realisations=4, fresh_test_series=20
    )
    finished = {"search": False}

    def progress(report) -> None:
        finished["search"] = report.timesteps >= request.timesteps

    kept = search_with_baselines(paper, request, seed=0)
    stopped = search_with_baselines(
        paper, request, seed=0, progress=progress, should_stop=lambda: finished["search"]
    )
    assert kept.result.front["accuracy_source"] == "measured"
    assert stopped.result.front["accuracy_source"] == "predicted"
