"""One suite every classifier kind must pass, in the style of scikit-learn's
``parametrize_with_checks``: a new kind registers itself and is checked here at once.

What each kind does that the others do not (the science) is tested in its own module.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE, I0
from sklearn.metrics import f1_score

from inertia_id import InputError, Scenario, identify, simulate
from inertia_id.classifiers.registry import (
    CLASSIFIER_KINDS,
    CandidateClassifier,
    classifier_from_json,
    default_realisations,
    describe,
    document_bytes,
    kind_class,
    load_classifier,
    make_classifier,
    train_classifier,
)

N_TRAIN = 8  # realisations per candidate
N_FRESH = 6
#: Options that keep every fit to a fraction of a second.
FAST: dict[str, dict[str, Any]] = {
    "clustering": {"metric": "euclidean"},
    "nearest-centroid": {"metric": "euclidean"},
    "1nn": {"metric": "euclidean"},
    "minirocket": {},
    "likelihood": {},
    "least-squares": {},
    "marginal-likelihood": {},
}


def test_the_fast_options_cover_every_kind() -> None:
    assert set(FAST) == set(CLASSIFIER_KINDS)


@pytest.fixture(scope="module", params=CLASSIFIER_KINDS)
def kind(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture(scope="module")
def fitted(kind: str, paper: Scenario) -> CandidateClassifier:
    """The kind trained once per kind. Tests must not mutate it."""
    return train(paper, kind, seed=0)


@pytest.fixture(scope="module")
def fresh(paper: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Responses never seen in training."""
    return simulate(paper, GOOD_SEQUENCE, N_FRESH, np.random.default_rng(1)).dataset()


def train(scenario: Scenario, kind: str, *, seed: int, n: int = N_TRAIN) -> CandidateClassifier:
    rng = np.random.default_rng(seed)
    return train_classifier(scenario, GOOD_SEQUENCE, n, rng, kind=kind, **FAST[kind])


def telemetry(scenario: Scenario, omega: np.ndarray) -> dict[str, Any]:
    times = scenario.sample_times(len(GOOD_SEQUENCE))
    return {"time_s": times.tolist(), "omega_rad_s": np.asarray(omega).tolist()}


# What the kind declares.


def test_its_document_is_within_the_bound_a_training_is_checked_by(
    kind: str, fitted: CandidateClassifier, paper: Scenario
) -> None:
    # The service and `inertia-id train` refuse a training by this bound before it runs,
    # so that no classifier is made that `identify --classifier` cannot load: every number
    # the kind keeps is counted (a kind that kept more than it says would pass the bound).
    written = len(fitted.to_json().encode())
    bound = document_bytes(kind, paper, len(GOOD_SEQUENCE), N_TRAIN)
    assert written <= bound


def test_it_declares_what_it_is(kind: str) -> None:
    cls = kind_class(kind)
    assert cls.kind == kind and cls.FORMAT.startswith("inertia-id/")
    assert 1 <= cls.MIN_REALISATIONS <= cls.DEFAULT_REALISATIONS == default_realisations(kind)
    model = make_classifier(kind)
    assert type(model) is cls
    assert describe(model).split()[0] == kind
    if cls.METRICS:
        assert model.metric == cls.METRICS[0]
        for metric in cls.METRICS:
            assert make_classifier(kind, metric=metric).metric == metric
        with pytest.raises(InputError, match=r"metric must be one of .*, got 'cosine'"):
            make_classifier(kind, metric="cosine")
    else:
        assert isinstance(model.metric, str) and model.metric
        with pytest.raises(InputError, match=r"does not take option\(s\) \['metric'\]"):
            make_classifier(kind, metric="dtw")


# Shapes, predictions and scores.


def test_transform_gives_a_distance_to_every_candidate(
    fitted: CandidateClassifier, fresh: tuple[np.ndarray, np.ndarray]
) -> None:
    X, _ = fresh
    distances = fitted.transform(X)
    assert distances.shape == (len(X), 5)
    assert np.all(np.isfinite(distances)) and np.all(distances >= 0)
    one = fitted.transform(X[3])
    np.testing.assert_allclose(one, distances[3:4], rtol=1e-10)


def test_predict_is_the_nearest_candidate(
    fitted: CandidateClassifier, fresh: tuple[np.ndarray, np.ndarray]
) -> None:
    X, _ = fresh
    predicted = fitted.predict(X)
    assert predicted.shape == (len(X),) and np.issubdtype(predicted.dtype, np.integer)
    np.testing.assert_array_equal(predicted, fitted.transform(X).argmin(axis=1))


def test_evaluate_and_score_on_fresh_draws(
    fitted: CandidateClassifier, fresh: tuple[np.ndarray, np.ndarray]
) -> None:
    X, y = fresh
    scores = fitted.evaluate(X, y)
    assert set(scores) == {"f1", "accuracy", "confusion"}
    assert scores["accuracy"] >= 0.9, scores["confusion"]
    predicted = fitted.predict(X)
    assert scores["f1"] == pytest.approx(f1_score(y, predicted, average="macro"), rel=1e-12)
    assert scores["accuracy"] == pytest.approx(np.mean(predicted == y), rel=1e-12)
    np.testing.assert_array_equal(scores["confusion"].sum(axis=1), np.full(5, N_FRESH))
    assert fitted.score(X, y) == scores["f1"]


def test_training_scores_count_every_training_series(fitted: CandidateClassifier) -> None:
    assert fitted.confusion_.shape == (5, 5)
    np.testing.assert_array_equal(fitted.confusion_.sum(axis=1), np.full(5, N_TRAIN))
    assert fitted.accuracy_ == pytest.approx(np.trace(fitted.confusion_) / (5 * N_TRAIN))
    assert 0.9 <= fitted.f1_ <= 1.0


# "Matches none".


def test_novelty_thresholds_follow_the_training_distances(fitted: CandidateClassifier) -> None:
    thresholds = fitted.novelty_thresholds()
    assert thresholds.shape == (5,)
    assert np.all(np.isfinite(thresholds)) and np.all(thresholds > 0)
    np.testing.assert_array_equal(
        thresholds,
        fitted.novelty_factor * fitted.max_training_distance_,
    )


def test_identify_names_genuine_responses_and_refuses_strangers(
    fitted: CandidateClassifier,
    paper: Scenario,
    fresh: tuple[np.ndarray, np.ndarray],
    scenario_like: Callable[..., Scenario],
) -> None:
    X, _ = fresh
    thresholds = fitted.novelty_thresholds()
    for i in range(0, len(X), 3):
        verdict = identify(fitted, telemetry(paper, X[i]))
        distances = fitted.transform(X[i])[0]
        assert verdict.candidate_index == int(distances.argmin())
        np.testing.assert_allclose(list(verdict.distances.values()), distances, rtol=1e-10)
        assert verdict.threshold == pytest.approx(thresholds[verdict.candidate_index])
        assert not verdict.matches_none, (i, verdict.distances, verdict.threshold)
    # A body with 60 % or twice the inertia of I0 is none of the candidates.
    strangers = simulate(
        scenario_like({"light": 0.6 * I0, "heavy": 2.0 * I0}),
        GOOD_SEQUENCE,
        2,
        np.random.default_rng(6),
    )
    for omega in strangers.omega_measured.reshape(-1, *strangers.omega_measured.shape[2:]):
        verdict = identify(fitted, telemetry(paper, omega))
        assert verdict.matches_none, (verdict.distances, verdict.threshold)
        assert verdict.distances[verdict.candidate] > verdict.threshold


# Storage.


def test_json_round_trip_gives_identical_predictions(
    fitted: CandidateClassifier, fresh: tuple[np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    X, _ = fresh
    text = fitted.to_json()
    assert "pickle" not in text
    cls = type(fitted)
    for loaded in (classifier_from_json(text), cls.from_json(text), cls.from_json(text.encode())):
        assert type(loaded) is cls
        assert loaded.to_json() == text
        np.testing.assert_array_equal(loaded.transform(X), fitted.transform(X))
        np.testing.assert_array_equal(loaded.predict(X), fitted.predict(X))
        np.testing.assert_array_equal(loaded.novelty_thresholds(), fitted.novelty_thresholds())
        assert loaded.candidate_names_ == fitted.candidate_names_
        assert loaded.scenario_ == fitted.scenario_
        np.testing.assert_array_equal(loaded.sequence_, fitted.sequence_)
        assert (loaded.f1_, loaded.accuracy_) == (fitted.f1_, fitted.accuracy_)
        np.testing.assert_array_equal(loaded.confusion_, fitted.confusion_)
        assert loaded.metric == fitted.metric
    path = tmp_path / "classifier.json"
    fitted.save(path)
    assert load_classifier(path).to_json() == text
    assert cls.load(path).to_json() == text


def test_damaged_or_foreign_documents_are_refused(fitted: CandidateClassifier) -> None:
    doc = json.loads(fitted.to_json())
    tampered = json.loads(json.dumps(doc))
    tampered["classifier"]["f1"] = 0.123
    with pytest.raises(InputError, match=r"checksum mismatch: document says '[0-9a-f]{64}'"):
        classifier_from_json(json.dumps(tampered))
    cls = type(fitted)
    foreign = {**doc, "format": "someone/else"}
    refusal = rf"not an {cls.FORMAT} document \(format 'someone/else'\)"
    with pytest.raises(InputError, match=refusal):
        cls.from_json(json.dumps(foreign))
    with pytest.raises(InputError, match="format 'someone/else' is not one of"):
        classifier_from_json(json.dumps(foreign))
    payload = {k: v for k, v in doc["classifier"].items() if k != "confusion"}
    with pytest.raises(InputError, match=rf"not a valid {fitted.kind} classifier document"):
        cls.from_dict(payload)
    with pytest.raises(InputError, match="not JSON"):
        classifier_from_json("{")


# Refusals quote what they got.


def test_bad_series_are_refused_with_the_value(
    fitted: CandidateClassifier, fresh: tuple[np.ndarray, np.ndarray]
) -> None:
    X, y = fresh
    bad = X[:3].copy()
    bad[2, 5, 1] = np.nan
    with pytest.raises(InputError, match=r"series 2, sample 5, axis 1 is nan"):
        fitted.transform(bad)
    with pytest.raises(InputError, match=r"79 samples; the classifier was trained on 80"):
        fitted.predict(X[:, :79])
    with pytest.raises(InputError, match=r"\(n_series, length, 3\) in rad/s, got \(2, 80, 4\)"):
        fitted.predict(np.zeros((2, 80, 4)))
    with pytest.raises(InputError, match="numeric"):
        fitted.transform([["x", "y", "z"]])
    with pytest.raises(InputError, match=r"labels must lie in 0\.\.4 .* got \[7\]"):
        fitted.evaluate(X, np.where(y == 4, 7, y))


def test_bad_parameters_are_refused_with_the_value(kind: str) -> None:
    for factor in (0.5, True, float("nan")):
        refusal = rf"novelty_factor must be a number >= 1, got {factor!r}"
        with pytest.raises(InputError, match=refusal):
            make_classifier(kind, novelty_factor=factor)
    refusal = rf"the '{kind}' classifier does not take option\(s\) \['depth'\]"
    with pytest.raises(InputError, match=refusal):
        make_classifier(kind, depth=3)


def test_an_unfitted_classifier_says_so(kind: str, fresh: tuple[np.ndarray, np.ndarray]) -> None:
    model = make_classifier(kind)
    for use in (lambda: model.predict(fresh[0]), model.novelty_thresholds, model.to_json):
        with pytest.raises(InputError, match="not fitted yet"):
            use()


@pytest.mark.parametrize(
    "needy", [k for k in CLASSIFIER_KINDS if kind_class(k).MIN_REALISATIONS > 1]
)
def test_too_few_training_series_are_refused(needy: str, paper: Scenario) -> None:
    n = kind_class(needy).MIN_REALISATIONS - 1
    refusal = rf"at least {n + 1} time\(s\); series per candidate: \{[n] * 5}"
    with pytest.raises(InputError, match=refusal):
        train_classifier(paper, GOOD_SEQUENCE, n, np.random.default_rng(2), kind=needy)


# Fitting.


def test_same_seed_same_model(kind: str, paper: Scenario, fitted: CandidateClassifier) -> None:
    again = train(paper, kind, seed=0)
    assert again.to_json() == fitted.to_json()
    assert train(paper, kind, seed=1).to_json() != fitted.to_json()


def test_fit_then_predict_is_fit_predict(
    kind: str, paper: Scenario, fitted: CandidateClassifier
) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, N_TRAIN, np.random.default_rng(3)).dataset()
    model = make_classifier(kind, **FAST[kind])
    if kind == "marginal-likelihood":
        # Its noise components need three runs of the same realisations.
        with pytest.raises(InputError, match="use fit_components"):
            model.fit(X, y)
        return
    params = {"random_state": 5} if "random_state" in model.get_params() else {}
    a = make_classifier(kind, **FAST[kind], **params)
    b = make_classifier(kind, **FAST[kind], **params)
    context = {"scenario": paper, "sequence": GOOD_SEQUENCE}
    predicted = a.fit_predict(X, y, **context)
    np.testing.assert_array_equal(predicted, b.fit(X, y, **context).predict(X))
    assert b.scenario_ == paper and b.candidate_names_ == paper.candidate_names
    with pytest.raises(InputError, match="give the scenario and the sequence together"):
        b.fit(X, y, scenario=paper)
    with pytest.raises(InputError, match=r"the 4-step sequence gives 80"):
        b.fit(X[:, :60], y, **context)
