"""inertia-id: which configuration is the spacecraft in, from how it rotates.

The science core, usable from a notebook::

    import numpy as np
    from inertia_id import Scenario, simulate, train, run_sweep, identify

    scenario = Scenario.paper()
    sequence = [[4, 4, 4, 0, 0, 0]] * 4
    result = simulate(scenario, sequence, 20, np.random.default_rng(0))
    classifier = train(scenario, sequence, 20, np.random.default_rng(1), metric="dtw")
"""

from .classify import METRICS, InertiaClassifier, MatchScores, match_clusters, train
from .identify import Identification, Telemetry, identify, load_telemetry, parse_telemetry
from .leastsquares import InertiaEstimate, LeastSquaresClassifier, estimate_inertia
from .likelihood import LikelihoodClassifier
from .marginal import MarginalLikelihoodClassifier, train_marginal
from .registry import (
    CLASSIFIER_KINDS,
    classifier_from_json,
    load_classifier,
    make_classifier,
    train_classifier,
)
from .scenario import (
    PRESETS,
    CandidateGenerator,
    InertiaCandidate,
    Scenario,
    Thrusters,
    Timing,
    Uncertainty,
    check_inertia_tensor,
    preset,
)
from .simulate import SimulationResult, Simulator, simulate
from .supervised import MiniRocketClassifier, NearestCentroidClassifier, NearestNeighbourClassifier
from .sweep import (
    InertiaSweepResult,
    SweepPoint,
    SweepResult,
    run_inertia_sweep,
    run_sweep,
    wilson_interval,
)

__version__ = "0.1.0"

__all__ = [
    "CLASSIFIER_KINDS",
    "METRICS",
    "PRESETS",
    "CandidateGenerator",
    "Identification",
    "InertiaCandidate",
    "InertiaClassifier",
    "InertiaEstimate",
    "InertiaSweepResult",
    "LeastSquaresClassifier",
    "LikelihoodClassifier",
    "MarginalLikelihoodClassifier",
    "MatchScores",
    "MiniRocketClassifier",
    "NearestCentroidClassifier",
    "NearestNeighbourClassifier",
    "Scenario",
    "SimulationResult",
    "Simulator",
    "SweepPoint",
    "SweepResult",
    "Telemetry",
    "Thrusters",
    "Timing",
    "Uncertainty",
    "check_inertia_tensor",
    "classifier_from_json",
    "estimate_inertia",
    "identify",
    "load_classifier",
    "load_telemetry",
    "make_classifier",
    "match_clusters",
    "parse_telemetry",
    "preset",
    "run_inertia_sweep",
    "run_sweep",
    "simulate",
    "train",
    "train_classifier",
    "train_marginal",
    "wilson_interval",
]
