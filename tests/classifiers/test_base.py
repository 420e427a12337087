"""The checks every kind shares, on their own: labels, integers, scores."""

from __future__ import annotations

import numpy as np
import pytest

from inertia_id import InputError
from inertia_id.classifiers.base import (
    check_int,
    check_labels,
    check_training_labels,
    confusion_scores,
)


@pytest.mark.parametrize(
    ("labels", "match"),
    [
        ([0, 1, 0, 1, 0], r"one label per series \(6\), got shape \(5,\)"),
        ([0, 1, 0.5, 1, 0, 1], r"labels must be candidate indices, got \[0\.0, 1\.0, 0\.5"),
        (["a", "b", "a", "b", "a", "b"], r"candidate indices, got \['a', 'b'"),
        ([0, 1, -1, 1, 0, 1], r"must be >= 0, got -1"),
        ([0, 0, 0, 0, 0, 0], r"\(K >= 2\) at least 2 time\(s\); series per candidate: \[6\]"),
        ([0, 2, 0, 2, 0, 2], r"series per candidate: \[3, 0, 3\]"),
        ([0, 1, 0, 1, 0, 2], r"at least 2 time\(s\); series per candidate: \[3, 2, 1\]"),
    ],
)
def test_training_labels_are_refused_with_what_was_given(labels: list[object], match: str) -> None:
    with pytest.raises(InputError, match=match):
        check_training_labels(labels, 6, minimum=2)


def test_whole_float_labels_are_candidate_indices() -> None:
    labels = check_training_labels(np.array([0.0, 1.0, 0.0, 1.0]), 4, minimum=2)
    assert labels.dtype.kind == "i" and labels.tolist() == [0, 1, 0, 1]


def test_evaluation_labels_must_name_a_candidate() -> None:
    assert check_labels([0, 4, 2], 3, 5).tolist() == [0, 4, 2]
    with pytest.raises(InputError, match=r"lie in 0\.\.4 \(candidate indices\), got \[5, 7\]"):
        check_labels([7, 5, 2], 3, 5)


@pytest.mark.parametrize("value", [0, -3, True, 2.0, "3", None])
def test_check_int_refuses_anything_but_an_integer(value: object) -> None:
    with pytest.raises(InputError, match=rf"n_init must be an integer >= 1, got {value!r}"):
        check_int("n_init", value)


def test_confusion_scores_average_over_the_candidates_present() -> None:
    confusion = np.array([[3, 1, 0], [0, 4, 0], [0, 0, 0]])
    scores = confusion_scores(confusion)
    # F1 of candidate 0: 2*3/(3+4) = 6/7; of candidate 1: 2*4/(5+4) = 8/9; 2 is absent.
    assert scores["f1"] == pytest.approx((6 / 7 + 8 / 9) / 2)
    assert scores["accuracy"] == pytest.approx(7 / 8)
    assert scores["confusion"] is confusion


def test_candidates_fitted_without_names_are_numbered_from_one() -> None:
    """A classifier fitted on arrays alone named its candidates "candidate 0", "candidate
    1", ... while plan tables and identify's candidate_number count from 1: the label now
    carries the same number."""
    from inertia_id import NearestCentroidClassifier

    rng = np.random.default_rng(0)
    X = np.concatenate([rng.normal(k, 0.1, (3, 8, 3)) for k in range(3)])
    y = np.repeat(np.arange(3), 3)
    model = NearestCentroidClassifier(metric="euclidean").fit(X, y)
    assert model.candidate_names_ == ["candidate 1", "candidate 2", "candidate 3"]
