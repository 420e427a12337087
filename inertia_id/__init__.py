"""inertia-id: which configuration is the spacecraft in, from how it rotates.

The science core, usable from a notebook::

    import numpy as np
    from inertia_id import Scenario, simulate, train, run_sweep, identify

    scenario = Scenario.paper()
    sequence = [[4, 4, 4, 0, 0, 0]] * 4
    result = simulate(scenario, sequence, 20, np.random.default_rng(0))
    classifier = train(scenario, sequence, 20, np.random.default_rng(1), metric="dtw")
"""

from .classifiers.clustering import METRICS, InertiaClassifier, MatchScores, match_clusters, train
from .classifiers.leastsquares import LeastSquaresClassifier
from .classifiers.likelihood import LikelihoodClassifier
from .classifiers.marginal import MarginalLikelihoodClassifier, train_marginal
from .classifiers.nearest import (
    MiniRocketClassifier,
    NearestCentroidClassifier,
    NearestNeighbourClassifier,
)
from .classifiers.registry import (
    CLASSIFIER_KINDS,
    classifier_from_json,
    load_classifier,
    make_classifier,
    train_classifier,
)
from .evaluation.identify import Identification, identify
from .evaluation.sweep import (
    InertiaSweepResult,
    SweepPoint,
    SweepResult,
    run_inertia_sweep,
    run_sweep,
    wilson_interval,
)
from .evaluation.telemetry import Telemetry, load_telemetry, parse_telemetry
from .physics.estimate import InertiaEstimate, estimate_inertia
from .physics.presets import PRESETS, preset
from .physics.scenario import (
    CandidateGenerator,
    InertiaCandidate,
    Scenario,
    Thrusters,
    Timing,
    Uncertainty,
    check_inertia_tensor,
)
from .physics.simulate import SimulationResult, Simulator, simulate

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
