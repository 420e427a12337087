"""``inertia-id search``: the actuation sequence that best separates the candidates."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from ..pipelines import SearchRequest
from .options import (
    LazyChoice,
    friendly_errors,
    load_scenario,
    out_option,
    parse_pairs,
    parse_radius,
    progress_bar,
    scenario_options,
    seed_option,
)

if TYPE_CHECKING:
    from ..physics.scenario import Scenario
    from ..pipelines import SearchOutcome

__all__ = ["search_cmd", "search_options", "search_request", "search_with_progress"]

F = TypeVar("F", bound=Callable[..., Any])


def _methods() -> tuple[str, ...]:
    from ..search import SEARCH_METHODS

    return SEARCH_METHODS


def _objectives() -> tuple[str, ...]:
    from ..search import SCORER_OBJECTIVES

    return SCORER_OBJECTIVES


def _metrics() -> tuple[str, ...]:
    from ..search import SCORER_METRICS

    return SCORER_METRICS


def _option(flags: str, field: str, help_text: str, **kwargs: Any) -> Callable[[F], F]:
    """An option whose default is the search request's: ``flags`` is "--flag" or
    "--flag name" (the parameter name the command gets)."""
    default = kwargs.pop("default", SearchRequest.default(field))
    return click.option(
        *flags.split(), default=default, show_default=True, help=help_text, **kwargs
    )


def _pairs(flag: str, help_text: str) -> Callable[[F], F]:
    name = f"{flag.removeprefix('--')}_pairs"
    return click.option(flag, name, multiple=True, metavar="NAME=VALUE", help=help_text)


def search_options(func: F) -> F:
    """How a search scores and spends its budget (``search`` and ``paper``)."""
    radius = SearchRequest.default("sakoe_chiba_radius")
    options = [
        _option(
            "--length sequence_length",
            "sequence_length",
            "Actuation steps L of the sequence.",
            type=click.IntRange(1, 50),
        ),
        _option(
            "--timesteps",
            "timesteps",
            "Environment-step budget (ppo, cem, random).",
            type=click.IntRange(1),
        ),
        _option(
            "--objective",
            "objective",
            "What scores a sequence: f1, the clustering F1 (the paper's), or separability, "
            "the Bhattacharyya separability bound (no clustering, much faster).",
            type=LazyChoice(_objectives),
        ),
        _option(
            "--search-metric search_metric",
            "metric",
            "Clustering metric that scores sequences: dtw (the paper's), euclidean or "
            "softdtw (slow).",
            type=LazyChoice(_metrics),
        ),
        _option(
            "--radius",
            "sakoe_chiba_radius",
            "DTW Sakoe-Chiba band half-width in samples, or 'none'.",
            default="none" if radius is None else str(radius),
        ),
        _option(
            "--search-realisations search_realisations",
            "n_realisations",
            "Realisations per candidate in each environment step.",
            type=click.IntRange(1),
        ),
        _option(
            "--fuel-weight",
            "fuel_weight",
            "Reward cost per N m s of commanded impulse.",
            type=click.FloatRange(0),
        ),
        _option(
            "--patience",
            "patience_episodes",
            "ppo/cem/random: stop once F1 = 1 and no better sequence came for this many episodes.",
            type=click.IntRange(1),
        ),
        _pairs(
            "--cem", "Override a CEM setting (repeatable): population, elite_fraction, smoothing."
        ),
        _pairs("--ppo", "Override a PPO hyperparameter (repeatable), e.g. --ppo n_steps=1024."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def search_request(
    method: str,
    *,
    sequence_length: int,
    timesteps: int,
    objective: str,
    search_metric: str,
    radius: str,
    search_realisations: int,
    fuel_weight: float,
    patience: int,
    ppo_pairs: tuple[str, ...],
    cem_pairs: tuple[str, ...],
    max_sequences: int | None = None,
) -> SearchRequest:
    """The options of :func:`search_options` as a request."""
    from ..errors import InputError

    if ppo_pairs and method != "ppo":
        raise InputError(f"--ppo applies to --method ppo only, not {method!r}")
    if cem_pairs and method != "cem":
        raise InputError(f"--cem applies to --method cem only, not {method!r}")
    return SearchRequest(
        method=method,
        sequence_length=sequence_length,
        timesteps=timesteps,
        max_sequences=SearchRequest.default("max_sequences")
        if max_sequences is None
        else max_sequences,
        n_realisations=search_realisations,
        objective=objective,
        metric=search_metric,
        sakoe_chiba_radius=parse_radius(radius),
        fuel_weight=fuel_weight,
        patience_episodes=patience,
        ppo=parse_pairs(ppo_pairs, "--ppo", "ent_coef=0.01"),
        cem=parse_pairs(cem_pairs, "--cem", "population=64"),
    )


def search_with_progress(
    scenario: Scenario, request: SearchRequest, *, seed: int, policy_path: str | None = None
) -> SearchOutcome:
    """The search with a progress bar on stderr, and its summary line after it."""
    from ..pipelines import search_with_baselines
    from ..search import SearchProgress, space_size

    size = space_size(scenario, request.sequence_length)
    click.echo(
        f"searching ({request.method}) for a {request.sequence_length}-step sequence in a space "
        f"of ({scenario.n_levels}^{scenario.n_thrusters})^{request.sequence_length} = "
        f"{size:.4g} sequences",
        err=True,
    )
    if request.method == "exhaustive":
        total = size * request.sequence_length if size <= request.max_sequences else 1
    else:
        total = request.timesteps
    with progress_bar(total, request.method, unit="step") as bar:

        def progress(report: SearchProgress) -> None:
            bar.update(report.timesteps - bar.n)
            bar.set_postfix(
                reward=f"{report.point.mean_episode_reward:.3f}",
                best_f1=f"{report.point.best_f1:.3f}",
            )

        outcome = search_with_baselines(
            scenario, request, seed=seed, policy_path=policy_path, progress=progress
        )
    click.echo(outcome.result.summary(), err=True)
    return outcome


@click.command("search")
@scenario_options
@_option(
    "--method",
    "method",
    "ppo (the paper's reinforcement learning), cem (the cross-entropy method), exhaustive "
    "(small spaces) or random (the baseline).",
    type=LazyChoice(_methods),
)
@search_options
@_option(
    "--max-sequences",
    "max_sequences",
    "exhaustive: refuse spaces larger than this.",
    type=click.IntRange(1),
)
@click.option(
    "--policy",
    "policy_path",
    type=click.Path(dir_okay=False),
    help="ppo: save the trained policy here (stable-baselines3 zip).",
)
@seed_option
@out_option("search.json", "Where to write the search JSON.")
@friendly_errors
def search_cmd(
    preset_name: str,
    scenario_path: str | None,
    method: str,
    max_sequences: int,
    policy_path: str | None,
    seed: int,
    out: str,
    **options: Any,
) -> None:
    """Find the actuation sequence that best separates the candidates.

    Writes the best sequence, its F1 on the search's noise draw and on fresh draws, its
    fuel and final rate, the learning curve, and the hand-designed baselines scored on
    the same fresh draws, as JSON.
    """
    import numpy as np

    scenario = load_scenario(preset_name, scenario_path)
    request = search_request(method, max_sequences=max_sequences, **options)
    outcome = search_with_progress(scenario, request, seed=seed, policy_path=policy_path)
    result = outcome.result
    click.echo(
        f"on the same fresh draws: found F1 {result.fresh.f1_mean:.3f}, "
        f"{result.best.fuel_nms:.1f} N m s, final rate {result.best.final_rate_rad_s:.3f} rad/s",
        err=True,
    )
    for name, base in outcome.baselines.items():
        f1, rate = np.mean(base["fresh_f1"]), np.mean(base["fresh_final_rate_rad_s"])
        click.echo(
            f"  {name:14s} F1 {f1:.3f}, {base['fuel_nms']:.1f} N m s, final rate {rate:.3f} rad/s",
            err=True,
        )
    Path(out).write_text(json.dumps(outcome.to_dict()), encoding="utf-8")
    click.echo(f"wrote {out}", err=True)
    click.echo(json.dumps(result.best.sequence))
