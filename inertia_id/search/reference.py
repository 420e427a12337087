"""The plain environment step of the search: the yardstick of the fast scorer.

:func:`plain_prefix_score` re-simulates the whole prefix series by series
(:func:`~inertia_id.physics.reference.simulate_per_series`), then clusters with tslearn's
``TimeSeriesKMeans(metric="dtw")`` and its defaults: the baseline of
``bench/search_env.py``. Not for production use.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..classifiers.clustering import match_clusters
from ..physics.reference import simulate_per_series
from ..physics.scenario import Scenario
from ..physics.simulate import SequenceNoise

__all__ = ["plain_prefix_score"]


def plain_prefix_score(
    scenario: Scenario, prefix: np.ndarray, noise: SequenceNoise, *, random_state: int = 0
) -> tuple[float, float]:
    """F1 and mean final rate of ``prefix``, the plain way; returns (f1, rad/s).

    The whole prefix is re-simulated one series at a time, then clustered by tslearn's
    ``TimeSeriesKMeans(n_clusters=K, metric="dtw")`` with its defaults (one k-means++
    run, unconstrained DTW, 100 DBA iterations).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from tslearn.clustering import TimeSeriesKMeans

    omega = simulate_per_series(scenario, prefix, noise)
    k, n, t, _ = omega.shape
    labels = np.repeat(np.arange(k), n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = TimeSeriesKMeans(n_clusters=k, metric="dtw", random_state=random_state)
        clusters = model.fit_predict(omega.reshape(k * n, t, 3))
    f1 = match_clusters(labels, clusters, k).f1
    # The true final rate: the last measured sample less its gyro bias and noise.
    last = noise.steps[len(prefix) - 1]
    true_final = omega[:, :, -1, :] - noise.initial.gyro_bias - last.gyro_noise[:, :, -1, :]
    return f1, float(np.linalg.norm(true_final, axis=-1).mean())
