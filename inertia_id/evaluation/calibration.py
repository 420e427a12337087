"""How far to trust a classifier's posterior: temperature, novelty tail and reliability,
measured on fresh simulated draws.

:func:`calibrate` simulates ``n`` new responses per candidate of the classifier's own
scenario and sequence (at 1x noise), fits on one half what the posterior needs
(:meth:`~inertia_id.classifiers.base.BaseClassifier.posterior_from_distances`): the
novelty tail of the own-candidate distances and the softmax temperature of least
held-out negative log-likelihood, and measures on the other half the expected
calibration error (ECE) and the reliability diagram (per confidence bin: mean
confidence, accuracy, count). The report is stored in the classifier
(``calibration_``, a JSON object in its document).

The temperature is only ever >= 1 (the posterior softened, never sharpened): on draws
a classifier separates perfectly, the likelihood of the fitting half grows without end
as the temperature falls, and sharpening beyond the model's own likelihood is not
something a finite set of draws can justify.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import minimize_scalar

from ..classifiers.base import NONE_PRIOR, NoveltyTail, check_int
from ..classifiers.gaussian import log_softmax
from ..errors import InputError
from ..physics.simulate import simulate
from ..stopping import Checkpoint, no_checkpoint

if TYPE_CHECKING:
    from ..classifiers.registry import CandidateClassifier

__all__ = ["calibrate", "reliability"]

#: Largest temperature tried, as its natural log.
_MAX_LOG_TEMPERATURE = 7.0


def reliability(
    confidence: np.ndarray, correct: np.ndarray, bins: int = 10
) -> tuple[float, list[dict[str, float]]]:
    """Expected calibration error and the reliability diagram of ``bins`` equal-width
    confidence bins on [0, 1] (empty bins left out).

    :param confidence: (n,) probability given to the predicted hypothesis.
    :param correct: (n,) whether the prediction was right.
    """
    check_int("bins", bins, 2)
    confidence = np.asarray(confidence, dtype=float)
    correct = np.asarray(correct, dtype=bool)
    index = np.minimum((confidence * bins).astype(int), bins - 1)
    table = []
    ece = 0.0
    for b in range(bins):
        inside = index == b
        count = int(inside.sum())
        if not count:
            continue
        mean_confidence = float(confidence[inside].mean())
        accuracy = float(correct[inside].mean())
        ece += count * abs(accuracy - mean_confidence)
        table.append(
            {
                "low": b / bins,
                "high": (b + 1) / bins,
                "mean_confidence": mean_confidence,
                "accuracy": accuracy,
                "count": count,
            }
        )
    return ece / max(len(confidence), 1), table


def calibrate(
    classifier: CandidateClassifier,
    n: int = 100,
    *,
    rng: np.random.Generator | None = None,
    bins: int = 10,
    checkpoint: Checkpoint = no_checkpoint,
) -> dict[str, Any]:
    """Fit the posterior's temperature and novelty tail on fresh draws and report its
    calibration; the report is stored in the classifier (``calibration_``).

    :param classifier: a fitted classifier that carries its scenario and sequence.
    :param n: fresh responses per candidate (>= 4), half to fit, half to measure.
    :param rng: source of the draws; default a fixed seed of its own, so a calibration
        repeats.
    :param bins: confidence bins of the reliability diagram (10 to 15 are usual).
    :param checkpoint: called after the draws and after their distances (a training's,
        :mod:`inertia_id.stopping`): it may stop the calibration there, by raising.
    :returns: temperature, novelty tail, none prior, held-out accuracy, ECE, the
        reliability bins and the number of draws.
    """
    check_int("n", n, 4)
    scenario, sequence = classifier.scenario_, classifier.sequence_
    if scenario is None or sequence is None:
        raise InputError("calibrate needs a classifier that carries its scenario and sequence")
    # A seed of its own: not the 0 a training is often given, whose draws it would repeat.
    rng = np.random.default_rng(0xCA11B) if rng is None else rng
    X, y = simulate(scenario, sequence, n, rng).dataset()
    checkpoint()
    distances = classifier.transform(X)
    checkpoint()
    fit = np.arange(len(y)) % 2 == 0
    held = ~fit
    model: Any = classifier
    tail = NoveltyTail.fit(distances[fit][np.arange(int(fit.sum())), y[fit]])
    if tail is not None:
        model.novelty_tail_ = tail
    model.calibration_ = None
    scale = model._evidence_scale()
    squared = distances[fit] ** 2

    def held_out_loss(log_temperature: float) -> float:
        logits = -0.5 * squared / (scale * math.exp(log_temperature))
        return -float(np.mean(log_softmax(logits, axis=1)[np.arange(len(squared)), y[fit]]))

    found = minimize_scalar(held_out_loss, bounds=(0.0, _MAX_LOG_TEMPERATURE), method="bounded")
    # The bounded search never evaluates the bound itself: keep T = 1 when it is as good.
    log_temperature = float(found.x) if found.fun < held_out_loss(0.0) else 0.0
    model.calibration_ = {"temperature": math.exp(log_temperature)}
    candidates, p_none = model.predict_posterior(X[held])
    hypotheses = np.concatenate([candidates, p_none[:, None]], axis=1)
    predicted = hypotheses.argmax(axis=1)
    correct = predicted == y[held]
    ece, table = reliability(hypotheses.max(axis=1), correct, bins)
    report = {
        "temperature": math.exp(log_temperature),
        "novelty_tail": None if model.novelty_tail_ is None else model.novelty_tail_.to_dict(),
        "none_prior": NONE_PRIOR,
        "n_per_candidate": n,
        "n_held_out": int(held.sum()),
        "accuracy": float(correct.mean()),
        "false_none_rate": float(np.mean(predicted == classifier.n_candidates_)),
        "mean_p_none": float(p_none.mean()),
        "ece": ece,
        "bins": table,
    }
    model.calibration_ = report
    return report
