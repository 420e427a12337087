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
from .sweep import SweepPoint, SweepResult, run_sweep, wilson_interval

__version__ = "0.1.0"

__all__ = [
    "METRICS",
    "PRESETS",
    "CandidateGenerator",
    "Identification",
    "InertiaCandidate",
    "InertiaClassifier",
    "MatchScores",
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
    "identify",
    "load_telemetry",
    "match_clusters",
    "parse_telemetry",
    "preset",
    "run_sweep",
    "simulate",
    "train",
    "wilson_interval",
]
