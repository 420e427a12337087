"""CPU time of ``identify`` with a start search, the conditioned model updated by rank 3
(as shipped) against the same model factored afresh at every start (as before).

Every start a verdict is given at conditions the default kind on the offset measured
before it (:meth:`MarginalLikelihoodClassifier.conditioned_on_offset`); a start refined
below the grid period is a new one each pass. The paper-in-orbit preset's default kind
(``train_marginal``, 40 realisations, the joint grid) judges ``--series`` 20 Hz passes of
the paper's 4-step sequence with 30 s before the start, each stated m + 1/2 periods after
its true start (m from -3 to 3: the search's grid starts then share one phase, as in the
tests), with ``estimate_start_within_s=--within``. The two ways run alternately, series
by series, CPU time (``time.process_time``) per call; the largest differences between
their verdicts are printed. Set ``OPENBLAS_NUM_THREADS=1`` for one BLAS thread.

Run: OPENBLAS_NUM_THREADS=1 python bench/start_search_cost.py [--series 30] [--within 0.3]
"""

from __future__ import annotations

import copy
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, begin, positive_int, print_table, write_json

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from inertia_id import simulate
from inertia_id.classifiers.marginal import MarginalLikelihoodClassifier, _Mixture, train_marginal
from inertia_id.evaluation.identify import identify
from inertia_id.evaluation.telemetry import Telemetry
from inertia_id.physics.presets import preset

SHIPPED = MarginalLikelihoodClassifier.conditioned_on_offset


#: The copies factored afresh, by offset variances: as before, the last four were kept.
_FACTORED: dict[bytes, _Mixture] = {}


def factored_afresh(
    self: MarginalLikelihoodClassifier,
    process_variance: np.ndarray,
    measurement_variance: np.ndarray,
    condition_log_weights: np.ndarray | None = None,
) -> MarginalLikelihoodClassifier:
    """The conditioned copy with its mixture factored from its covariances, as before
    (kept per pair of variances, as before, so the search's starts reuse it)."""
    model = SHIPPED(self, process_variance, measurement_variance, condition_log_weights)
    key = np.concatenate([process_variance.ravel(), measurement_variance.ravel()])
    key = key.round(15).tobytes()
    if key not in _FACTORED:
        if len(_FACTORED) >= 4:
            _FACTORED.pop(next(iter(_FACTORED)))
        _FACTORED[key] = _Mixture(
            model.means_.reshape(model.n_candidates_, -1), model.components_, model.grid_
        )
    fresh = copy.copy(model)
    fresh.__dict__ = {**model.__dict__, "_observed_mixtures": {}}
    mixture = _FACTORED[key]
    weights = condition_log_weights
    fresh._mixture = mixture if weights is None else mixture.reweighted(weights)
    return fresh


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--series", type=positive_int, default=30, help="passes judged")
    parser.add_argument("--within", type=float, default=0.3, help="start search ±, s")
    args = begin(parser, "identify with a start search: rank-3 update vs factored afresh")
    scenario = preset("paper-in-orbit")
    classifier = train_marginal(scenario, GOOD_SEQUENCE, 40, np.random.default_rng(11))
    quiet = [[0] * scenario.n_thrusters]
    period = 1.0 / scenario.timing.sample_rate_hz
    rng = np.random.default_rng(args.seed)
    passes = []
    for i in range(args.series):
        flown = simulate(scenario, quiet * 30 + GOOD_SEQUENCE + quiet * 2, 1, rng.spawn(1)[0])
        passes.append(
            Telemetry(
                time_s=(flown.time_s - 30.0).tolist(),
                omega_rad_s=flown.omega_measured[i % classifier.n_candidates_, 0].tolist(),
                sequence_start=(int(rng.integers(-3, 4)) + 0.5) * period,
            )
        )
    ways = {"rank-3 update (shipped)": SHIPPED, "factored afresh (before)": factored_afresh}
    times: dict[str, list[float]] = {name: [] for name in ways}
    verdicts: dict[str, list[Any]] = {name: [] for name in ways}
    for way in ways.values():  # warm-up: the offset-free mixture, numpy's first calls
        MarginalLikelihoodClassifier.conditioned_on_offset = way  # type: ignore[method-assign]
        identify(classifier, passes[0], estimate_start_within_s=args.within)
    try:
        for i, telemetry in enumerate(passes):
            for name in list(ways) if i % 2 == 0 else list(ways)[::-1]:
                MarginalLikelihoodClassifier.conditioned_on_offset = ways[name]  # type: ignore[method-assign]
                began = time.process_time()
                verdict = identify(classifier, telemetry, estimate_start_within_s=args.within)
                times[name].append(1e3 * (time.process_time() - began))
                verdicts[name].append(verdict)
    finally:
        MarginalLikelihoodClassifier.conditioned_on_offset = SHIPPED  # type: ignore[method-assign]
    rows = [
        [
            name,
            f"{statistics.median(ms):.1f}",
            f"{min(ms):.1f}",
            f"{max(ms):.1f}",
            sum(bool(v.sequence_start_refined) for v in verdicts[name]),
        ]
        for name, ms in times.items()
    ]
    print_table(["conditioned model", "median ms", "least ms", "most ms", "refined"], rows)
    shipped, before = verdicts.values()
    posterior = max(
        abs(a.posterior[k] - b.posterior[k])
        for a, b in zip(shipped, before, strict=True)
        for k in a.posterior
    )
    distance = max(
        abs(a.distances[k] / b.distances[k] - 1.0)
        for a, b in zip(shipped, before, strict=True)
        for k in a.distances
    )
    shift = max(
        abs(a.sequence_start_shift_s - b.sequence_start_shift_s)
        for a, b in zip(shipped, before, strict=True)
    )
    print(
        f"largest differences: posterior {posterior:.1e}, relative distance {distance:.1e}, "
        f"start {shift:.1e} s"
    )
    write_json(
        args.json,
        args,
        {
            "cpu_ms": times,
            "largest_posterior_difference": posterior,
            "largest_relative_distance_difference": distance,
            "largest_start_difference_s": shift,
        },
    )


if __name__ == "__main__":
    main()
