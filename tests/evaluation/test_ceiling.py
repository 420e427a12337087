"""The ceiling of a sweep: no classifier kind beats it beyond the sampling error."""

from __future__ import annotations

import numpy as np

from inertia_id import Scenario, run_sweep, train_classifier
from inertia_id.classifiers.registry import CLASSIFIER_KINDS, kind_class
from inertia_id.evaluation.ceiling import DEFAULT_CEILING_REALISATIONS
from inertia_id.pipelines import SweepRequest

SEQUENCE = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]


def _specs() -> dict[str, tuple[str, dict[str, str]]]:
    specs: dict[str, tuple[str, dict[str, str]]] = {}
    for kind in CLASSIFIER_KINDS:
        metrics = [m for m in kind_class(kind).METRICS if m != "softdtw"]  # softdtw: minutes
        for metric in metrics or [None]:
            label = kind if metric is None else f"{kind}:{metric}"
            specs[label] = (kind, {} if metric is None else {"metric": metric})
    return specs


def test_no_kind_beats_the_ceiling_beyond_the_sampling_error(paper: Scenario) -> None:
    rng = np.random.default_rng(3)
    others = {
        label: train_classifier(
            paper, SEQUENCE, kind_class(kind).DEFAULT_REALISATIONS, rng, kind=kind, **options
        )
        for label, (kind, options) in _specs().items()
    }
    main = others.pop("marginal-likelihood")
    sweep = run_sweep(
        main,
        others=others,
        multiples=(1, 4, 8),
        noises=("process", "measurement", "jitter"),
        n_test=250,
        ceiling_realisations=1000,
        seed=5,
    )
    assert len(sweep.ceiling) == 9 and sweep.ceiling == sweep.limit
    assert len(sweep.ceiling_covariance) == 9
    assert set(sweep.ceiling_covariance) <= {"sample", "noise model"}
    beaten = []
    for label, points in {"marginal-likelihood": sweep.points, **sweep.others}.items():
        for point, ceiling in zip(points, sweep.ceiling, strict=True):
            assert (point.noise, point.multiple) == (ceiling.noise, ceiling.multiple)
            if point.accuracy > ceiling.ci_high:
                beaten.append(
                    (label, point.noise, point.multiple, point.accuracy, ceiling.accuracy)
                )
    assert not beaten


def test_the_ceiling_default_is_the_sweep_jobs(paper: Scenario) -> None:
    assert SweepRequest.default("ceiling_realisations") == DEFAULT_CEILING_REALISATIONS


def test_the_ceiling_rises_above_a_one_x_classifier_at_high_noise(paper: Scenario) -> None:
    model = train_classifier(paper, SEQUENCE, 20, np.random.default_rng(1), kind="likelihood")
    sweep = run_sweep(
        model, multiples=(8,), noises=("process",), n_test=400, ceiling_realisations=500, seed=2
    )
    assert sweep.ceiling[0].accuracy >= sweep.points[0].accuracy
    assert sweep.ceiling_realisations == 500 == sweep.limit_realisations


def test_at_l8_the_sample_covariance_loses_and_the_ceiling_takes_the_noise_models(
    paper: Scenario,
) -> None:
    """At L = 8 the sample covariance of a 480-value series from 2,000 realisations costs
    accuracy: the Gaussians with the noise model's written-out covariance classify more
    of the same series (McNemar's exact test on the series the two disagree on). The
    ceiling picks the noise model's there, so nothing known beats it."""
    from scipy.stats import binomtest

    from inertia_id import simulate
    from inertia_id.evaluation.ceiling import fit_ceiling

    sequence = np.array(
        [[4, 4, 4, 0, 0, 0]] * 2
        + [[0] * 6] * 2
        + [[0, 0, 0, 4, 0, 0]] * 2
        + [[0, 0, 0, 0, 4, 4]] * 2
    )
    scales = {"process_noise_scale": 6.0, "measurement_noise_scale": 1.0}
    X, y = simulate(paper, sequence, 1000, np.random.default_rng(21), **scales).dataset()
    right = {}
    for covariance in ("sample", "noise model", "best"):
        fitted = fit_ceiling(
            paper, sequence, 2000, np.random.default_rng(22), covariance=covariance, **scales
        )
        right[covariance] = fitted.predict(X) == y
        assert fitted.source == ("noise model" if covariance == "best" else covariance)
    only_model = int(np.sum(right["noise model"] & ~right["sample"]))
    only_sample = int(np.sum(right["sample"] & ~right["noise model"]))
    p = binomtest(only_model, only_model + only_sample, 0.5, alternative="greater").pvalue
    assert p < 0.01, (only_model, only_sample)
    assert np.array_equal(right["best"], right["noise model"])


def test_the_ceiling_refuses_an_unknown_covariance(paper: Scenario) -> None:
    import pytest

    from inertia_id import InputError
    from inertia_id.evaluation.ceiling import fit_ceiling

    with pytest.raises(InputError, match="covariance must be 'best', 'sample' or 'noise model'"):
        fit_ceiling(paper, SEQUENCE, 10, np.random.default_rng(0), covariance="pooled")
