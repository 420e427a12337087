"""Search for the actuation sequence that makes the inertia candidates most distinguishable.

Five methods, one result shape (:class:`SearchResult`): :func:`ppo_search` (the paper's
reinforcement learning), :func:`cem_search` (the cross-entropy method),
:func:`exhaustive_search` (small spaces) and :func:`random_search` (the baseline) drive
:class:`SequenceSearchEnv`, registered with Gymnasium as ``InertiaId/SequenceSearch-v0``,
and score sequences by the objective of their :class:`ScorerSettings`: the clustering F1
("f1") or the separability bound ("separability"); :func:`pareto_search` (NSGA-II,
pymoo) finds a Pareto front of the operator's objectives (:class:`OperatorSettings`:
accuracy at a design noise, residual rate, impulse, propellant, ...).
"""

from typing import TYPE_CHECKING, Any

import gymnasium as gym

from ..errors import InputError
from ..physics.scenario import Scenario
from .cem import CEM_DEFAULTS, cem_search, check_cem_params
from .env import ENV_ID, SequenceSearchEnv
from .exhaustive import exhaustive_search
from .objectives import CONSTRAINTS, OPERATOR_OBJECTIVES, SequenceScores
from .operator import OperatorScorer, OperatorSettings
from .pareto import NSGA2_DEFAULTS, Front, build_front, check_nsga2_params, pareto_search
from .ppo import PPO_DEFAULTS, check_ppo_params, ppo_search
from .random import random_search
from .records import (
    CurvePoint,
    EpisodeRecord,
    FreshEvaluation,
    SearchProgress,
    SearchResult,
    SearchTracker,
    evaluate_sequence,
    space_size,
)
from .scorer import SCORER_METRICS, SCORER_OBJECTIVES, PrefixScore, PrefixScorer, ScorerSettings

if TYPE_CHECKING:
    from .callback import SearchCallback

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="inertia_id.search.env:SequenceSearchEnv")

SEARCH_METHODS = ("ppo", "cem", "exhaustive", "random", "nsga2")
#: What each method is, for a person choosing one.
SEARCH_METHOD_LABELS = {
    "ppo": "PPO (the paper's reinforcement learning)",
    "cem": "cross-entropy method (fast with the separability objective)",
    "exhaustive": "exhaustive (every sequence of a small space)",
    "random": "random sequences (the baseline)",
    "nsga2": "NSGA-II Pareto front of accuracy, residual rate and propellant (pymoo)",
}


def search(method: str, scenario: Scenario, **options: Any) -> SearchResult:
    """Run the search ``method`` ("ppo", "cem", "exhaustive" or "random") with its options."""
    if method == "ppo":
        return ppo_search(scenario, **options)
    if method == "cem":
        return cem_search(scenario, **options)
    if method == "exhaustive":
        return exhaustive_search(scenario, **options)
    if method == "random":
        return random_search(scenario, **options)
    if method == "nsga2":
        return pareto_search(scenario, **options)
    raise InputError(f"search method must be one of {list(SEARCH_METHODS)}, got {method!r}")


def __getattr__(name: str) -> Any:
    # SearchCallback subclasses stable-baselines3's: importing it imports torch, which
    # only a PPO search needs.
    if name == "SearchCallback":
        from .callback import SearchCallback

        return SearchCallback
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "CEM_DEFAULTS",
    "CONSTRAINTS",
    "ENV_ID",
    "NSGA2_DEFAULTS",
    "OPERATOR_OBJECTIVES",
    "PPO_DEFAULTS",
    "SCORER_METRICS",
    "SCORER_OBJECTIVES",
    "SEARCH_METHODS",
    "SEARCH_METHOD_LABELS",
    "CurvePoint",
    "EpisodeRecord",
    "FreshEvaluation",
    "Front",
    "OperatorScorer",
    "OperatorSettings",
    "PrefixScore",
    "PrefixScorer",
    "ScorerSettings",
    "SearchCallback",
    "SearchProgress",
    "SearchResult",
    "SearchTracker",
    "SequenceScores",
    "SequenceSearchEnv",
    "build_front",
    "cem_search",
    "check_cem_params",
    "check_nsga2_params",
    "check_ppo_params",
    "evaluate_sequence",
    "exhaustive_search",
    "pareto_search",
    "ppo_search",
    "random_search",
    "search",
    "space_size",
]
