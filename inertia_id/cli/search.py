"""``inertia-id search``: the actuation sequence that best separates the candidates."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

import click

from ..deadline import GRACE_ASKED_MAX_S, GRACE_MAX_S
from ..pipelines import SearchRequest
from ..wording import significant
from .options import (
    FloatRange,
    IntRange,
    LazyChoice,
    friendly_errors,
    load_scenario,
    out_option,
    parse_pairs,
    parse_radius,
    progress_bar,
    scenario_options,
    seed_option,
    time_limit_option,
    write_output,
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
            type=IntRange(1, 50),
        ),
        _option(
            "--timesteps",
            "timesteps",
            "Environment-step budget (ppo, cem, random).",
            type=IntRange(1),
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
            type=IntRange(1),
        ),
        _option(
            "--fuel-weight",
            "fuel_weight",
            "Reward cost per N m s of commanded impulse.",
            type=FloatRange(0),
        ),
        _option(
            "--patience",
            "patience_episodes",
            "ppo/cem/random: stop once F1 = 1 and no better sequence came for this many episodes.",
            type=IntRange(1),
        ),
        _pairs(
            "--cem", "Override a CEM setting (repeatable): population, elite_fraction, smoothing."
        ),
        _pairs("--ppo", "Override a PPO hyperparameter (repeatable), e.g. --ppo n_steps=1024."),
        _pairs(
            "--nsga2",
            "Override an NSGA-II setting (repeatable): population, generations, "
            "crossover_eta, mutation_eta, crossover_prob, polish_iterations, polish_starts.",
        ),
        click.option(
            "--objectives",
            default=",".join(SearchRequest.default("objectives")),
            show_default=True,
            help="What the front trades off, comma-separated: accuracy, final_rate, "
            "peak_rate, impulse, on_time, propellant, duration.",
        ),
        click.option(
            "--design-noise",
            default=";".join(f"{p:g},{q:g}" for p, q in SearchRequest.default("design_noise")),
            show_default=True,
            help="Where the accuracy is predicted: 'process,measurement' multiples, "
            "conditions separated by ';' (the objective is their mean).",
        ),
        _pairs(
            "--constraint",
            "A bound (repeatable): max_final_rate_deg_s, max_final_rate_rad_s (every "
            "candidate's residual rate, mean over flights: the total, any initial rate "
            "included, not the commanded part the listing gives beside it), "
            "max_final_rate_p95_deg_s, "
            "max_final_rate_p95_rad_s (a rate at least 95 % of every candidate's flights "
            "stay under, with 95 % confidence), max_commanded_residual_rate_deg_s, "
            "max_commanded_residual_rate_rad_s (the commanded part alone: the residual the "
            "plan predicts from rest with every noise off, mean over candidates), "
            "max_commanded_residual_rate_max_deg_s, max_commanded_residual_rate_max_rad_s "
            "(the same, the candidate the commands leave fastest), max_peak_rate_deg_s, "
            "max_peak_rate_rad_s "
            "(the fastest candidate's largest mean speed over the flights, or the plan's "
            "peak), max_peak_rate_p95_deg_s, "
            "max_peak_rate_p95_rad_s (a peak rate at least 95 % of its flights stay under), "
            "max_impulse_nms, max_on_time_s, max_propellant_kg, max_duration_s, "
            "min_accuracy; e.g. --constraint max_final_rate_deg_s=0.2.",
        ),
        _option(
            "--constraint-penalty",
            "constraint_penalty",
            "ppo/cem/random/exhaustive: reward cost per unit of relative constraint violation.",
            type=FloatRange(0),
        ),
        _option(
            "--lagrangian-lr",
            "lagrangian_lr",
            "ppo: raise the penalty after every rollout by this times the mean violation.",
            type=FloatRange(0),
        ),
        _option(
            "--fresh-realisations",
            "fresh_realisations",
            "Realisations per candidate when the front is re-scored on fresh draws.",
            type=IntRange(2),
        ),
        _option(
            "--fresh-test-series",
            "fresh_test_series",
            "Test series per candidate and design condition on which each front member's "
            "accuracy is measured; 0 keeps the prediction.",
            type=IntRange(0, 5000),
        ),
        time_limit_option(
            "Stop the search after this many seconds (wall clock) with the best found so "
            "far (stopped: time_limit), re-scored only in a grace of 10 % of the limit, at "
            f"least 10 s, at most {GRACE_MAX_S:g} s; none by default."
        ),
        _option(
            "--time-limit-grace time_limit_grace_s",
            "time_limit_grace_s",
            f"Seconds the re-score on fresh draws may go on past --time-limit, at most "
            f"{GRACE_ASKED_MAX_S:g} (0: stop at the limit); by default 10 % of the limit, at "
            f"least 10 s, at most {GRACE_MAX_S:g} s.",
            type=FloatRange(0, max=GRACE_ASKED_MAX_S),
            metavar="SECONDS",
        ),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def _given(name: str) -> bool:
    """Whether the command's option ``name`` was given (on the command line or from the
    environment), not left at its default."""
    from click.core import ParameterSource

    context = click.get_current_context(silent=True)
    return context is not None and context.get_parameter_source(name) in (
        ParameterSource.COMMANDLINE,
        ParameterSource.ENVIRONMENT,
    )


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
    nsga2_pairs: tuple[str, ...] = (),
    objectives: str | None = None,
    design_noise: str | None = None,
    constraint_pairs: tuple[str, ...] = (),
    constraint_penalty: float = 0.0,
    lagrangian_lr: float = 0.0,
    fresh_realisations: int | None = None,
    max_sequences: int | None = None,
    fresh_test_series: int | None = None,
    time_limit_s: float | None = None,
    time_limit_grace_s: float | None = None,
) -> SearchRequest:
    """The options of :func:`search_options` as a request."""
    from ..errors import InputError

    if time_limit_grace_s is not None and time_limit_s is None:
        # An option that would have no effect is refused rather than dropped.
        raise InputError("--time-limit-grace applies with --time-limit only")

    if ppo_pairs and method != "ppo":
        raise InputError(f"--ppo applies to --method ppo only, not {method!r}")
    if cem_pairs and method != "cem":
        raise InputError(f"--cem applies to --method cem only, not {method!r}")
    if nsga2_pairs and method != "nsga2":
        raise InputError(f"--nsga2 applies to --method nsga2 only, not {method!r}")
    weights = (
        ("--fuel-weight", fuel_weight),
        ("--constraint-penalty", constraint_penalty),
        ("--lagrangian-lr", lagrangian_lr),
    )
    for option, weight in weights:
        # Refused by the core's name (fuel_weight) once the search's bar had started.
        if not math.isfinite(weight):
            raise InputError(f"{option} {weight:g}: give a finite number >= 0")
    if lagrangian_lr and method != "ppo":
        raise InputError(f"--lagrangian-lr applies to --method ppo only, not {method!r}")
    if method == "nsga2":
        # NSGA-II has no reward: both were dropped without a word.
        for option, weight in weights[:2]:
            if weight:
                raise InputError(
                    f"{option} weighs the reward of --method ppo, cem, random or exhaustive; "
                    "nsga2 has none: it trades impulse off as an --objectives entry and "
                    "keeps every --constraint as a constraint"
                )
    if method in ("nsga2", "exhaustive"):
        # Their budgets are others (--nsga2 generations=..., every sequence): both options
        # ran and were dropped without a word.
        for option, name in (("--timesteps", "timesteps"), ("--patience", "patience")):
            if _given(name):
                raise InputError(
                    f"{option} applies to --method ppo, cem or random, not {method!r} "
                    + (
                        "(its budget is --nsga2 population=... generations=...)"
                        if method == "nsga2"
                        else "(it scores every sequence)"
                    )
                )
    pairs = SearchRequest.default("design_noise")
    if design_noise is not None:
        from ..checks import parse_decimal

        try:
            pairs = tuple(
                tuple(parse_decimal(v) for v in part.split(","))
                for part in design_noise.split(";")
                if part.strip()
            )
        except ValueError as exc:
            raise InputError(
                f"--design-noise takes 'process,measurement' pairs separated by ';', "
                f"got {design_noise!r}: {exc}"
            ) from None
        if not pairs or not all(len(pair) == 2 for pair in pairs):
            raise InputError(
                f"--design-noise takes 'process,measurement' pairs, got {design_noise!r}"
            )
    from ..search.objectives import OPERATOR_OBJECTIVES

    names = SearchRequest.default("objectives")
    if objectives is not None:
        names = tuple(s.strip() for s in objectives.split(",") if s.strip())
        if not names:
            # An empty list read as the default front before.
            raise InputError(
                f"--objectives names none, got {objectives!r}: give one or more of "
                f"{', '.join(OPERATOR_OBJECTIVES)}"
            )
    return SearchRequest(
        nsga2=parse_pairs(nsga2_pairs, "--nsga2", "generations=30"),
        objectives=names,
        design_noise=pairs,
        constraints=parse_pairs(constraint_pairs, "--constraint", "max_final_rate_deg_s=0.2"),
        constraint_penalty=constraint_penalty,
        lagrangian_lr=lagrangian_lr,
        fresh_realisations=SearchRequest.default("fresh_realisations")
        if fresh_realisations is None
        else fresh_realisations,
        fresh_test_series=SearchRequest.default("fresh_test_series")
        if fresh_test_series is None
        else fresh_test_series,
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
        time_limit_s=time_limit_s,
        time_limit_grace_s=time_limit_grace_s,
    )


def search_with_progress(
    scenario: Scenario, request: SearchRequest, *, seed: int, policy_path: str | None = None
) -> SearchOutcome:
    """The search with a progress bar on stderr, and its summary line after it; what
    :func:`~inertia_id.pipelines.check_search` refuses is refused before the first line
    (a rate bound below the initial-rate floor was refused inside the pipeline, after
    "searching (nsga2) ..." and the bar had started), and only there (the pipeline ran
    the checks again, and with them one more nominal simulation)."""
    from ..pipelines import check_search, search_with_baselines
    from ..search import SearchProgress, space_size

    check_search(scenario, request)
    size = space_size(scenario, request.sequence_length)
    click.echo(
        f"searching ({request.method}) for a {request.sequence_length}-step sequence in a space "
        f"of ({scenario.n_levels}^{scenario.n_thrusters})^{request.sequence_length} = "
        f"{size:.4g} sequences",
        err=True,
    )
    # NSGA-II's budget is generations, a polish that may stop early and the front's
    # measurement, not --timesteps: its bar shows the fraction of the job done.
    by_fraction = request.method == "nsga2"
    score = "f1" if request.objective == "f1" else "separability"
    if by_fraction:
        total, unit = 1000, "‰"
    elif request.method == "exhaustive":
        total = size * request.sequence_length if size <= request.max_sequences else 1
        unit = "step"
    else:
        total, unit = request.timesteps, "step"
    with progress_bar(total, request.method, unit=unit) as bar:

        def progress(report: SearchProgress) -> None:
            bar.update((round(1000 * report.fraction) if by_fraction else report.timesteps) - bar.n)
            if report.phase != "search":  # the search is done; say what runs now
                bar.set_postfix_str(report.phase)
            else:
                # The point's best_f1 is the objective's score: say which it is, and
                # whether that best meets the constraints (while none has, it is the
                # best of all: "feasible" would claim what it is not).
                best = f"best_{'accuracy' if by_fraction else score}"
                if request.constraints:
                    best += "_feasible" if report.point.best_feasible else "_none_feasible_yet"
                figures = {best: f"{report.point.best_f1:.3f}"}
                if not by_fraction:
                    figures = {"reward": f"{report.point.mean_episode_reward:.3f}", **figures}
                bar.set_postfix(figures)

        outcome = search_with_baselines(
            scenario, request, seed=seed, policy_path=policy_path, progress=progress, checked=True
        )
    click.echo(outcome.result.summary(), err=True)
    return outcome


def _rescore_cut(settings: dict[str, Any], front: dict[str, Any], fresh: Any) -> list[str]:
    """What a time limit left out of the re-score on fresh draws, one line each: the
    front's candidates not re-scored and the best's fresh draws fewer than asked (the
    dashboard's front panel says the same); none when nothing was left out."""
    left = front.get("not_rescored") or []
    asked, done = fresh.draws_asked, len(fresh.f1)
    fewer = asked is not None and asked > done
    limit, grace = settings.get("time_limit_s"), settings.get("time_limit_grace_s")
    if grace == 0:
        # A grace of 0 is the search's own choice (stop at the limit), not one running out.
        why = f"the time limit ({limit:g} s) was reached and no grace was asked for"
    elif grace is not None:
        why = f"the time limit's grace ({grace:g} s) was spent"
    else:
        why = "the re-score was stopped"
    lines = []
    if left:
        lines.append(
            f"+ {len(left)} candidate{'' if len(left) == 1 else 's'} not re-scored: {why}; "
            "the front above is judged without them"
        )
    if fewer:
        lines.append(f"the best sequence's F1 is on {done} of the {asked} fresh draws asked: {why}")
    return lines


@click.command("search")
@scenario_options
@_option(
    "--method",
    "method",
    "ppo (the paper's reinforcement learning), cem (the cross-entropy method), exhaustive "
    "(small spaces), random (the baseline) or nsga2 (a Pareto front of the operator's "
    "objectives).",
    type=LazyChoice(_methods),
)
@search_options
@_option(
    "--max-sequences",
    "max_sequences",
    "exhaustive: refuse spaces larger than this.",
    type=IntRange(1),
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
    impulse and rates (the residual once the lag is empty; |ω| at the last step's end),
    the learning curve, the front, and the baselines scored on the same fresh draws, as
    JSON.
    """
    import numpy as np

    from ..errors import InputError

    if policy_path is not None and method != "ppo":
        # Only PPO trains a policy: the file was silently never written.
        raise InputError(f"--policy applies to --method ppo only, not {method!r}")
    scenario = load_scenario(preset_name, scenario_path)
    request = search_request(method, max_sequences=max_sequences, **options)
    outcome = search_with_progress(scenario, request, seed=seed, policy_path=policy_path)
    result = outcome.result
    # Found and baselines alike on the same fresh draws: the clustering F1 and |ω| at the
    # last step's end (the front below gives the settled residual rate).
    if result.fresh.f1:
        click.echo(
            f"on the same fresh draws (F1; |ω| at the last step's end): found F1 "
            f"{result.fresh.f1_mean:.3f}, impulse {result.best.fuel_nms:.1f} N m s, end rate "
            f"{np.mean(result.fresh.final_rate_rad_s):.3f} rad/s "
            f"({np.degrees(np.mean(result.fresh.final_rate_rad_s)):.2f} deg/s)",
            err=True,
        )
    else:
        # A time limit (or its grace of 0) can leave the best no fresh draw: no mean of
        # nothing (it printed "F1 nan" with a RuntimeWarning); the lines below say why.
        click.echo(
            f"found: no fresh draw was scored (stopped: {result.stopped}), impulse "
            f"{result.best.fuel_nms:.1f} N m s",
            err=True,
        )
    for name, base in outcome.baselines.items():
        if "unavailable" in base:
            click.echo(f"  {name:16s} unavailable: {base['unavailable']}", err=True)
            continue
        f1, rate = np.mean(base["fresh_f1"]), np.mean(base["fresh_final_rate_rad_s"])
        click.echo(
            f"  {name:16s} F1 {f1:.3f}, impulse {base['fuel_nms']:.1f} N m s, end rate "
            f"{rate:.3f} rad/s ({np.degrees(rate):.2f} deg/s)",
            err=True,
        )
    front = result.front or {}
    how = (
        f"measured on {front.get('fresh_test_series')} fresh series per candidate"
        if front.get("accuracy_source") == "measured"
        else "predicted"
    )
    click.echo(
        f"front on fresh draws (accuracy at each design noise, {how} | residual rate once "
        "the lag is empty, mean and worst candidate; the part the commands leave, from rest "
        "| impulse):",
        err=True,
    )
    for member in front.get("members", []):
        scores = member["scores"]
        flags = (
            f"  dominated by {', '.join(member['dominated_by'])}" if member["dominated_by"] else ""
        )
        if member.get("feasible") is False:
            # A searcher other than NSGA-II keeps its best sequence even when it breaks one.
            flags += "  BREAKS A CONSTRAINT"
        click.echo(
            f"  #{member['index']:<3d} {json.dumps(member['sequence'])}  acc "
            + "/".join(f"{a:.3f}" for a in scores["accuracy_by_noise"])
            + f" | {scores['final_rate_rad_s']:.4f} rad/s ({scores['final_rate_deg_s']:.2f} deg/s)"
            + f", worst {scores['final_rate_max_rad_s']:.4f}"
            + (
                # Three significant digits, as the dashboard: the figure tells braking
                # sequences apart below 0.001 rad/s, where :.4f wrote 0.0001 or 0.0000.
                f"; commanded (from rest) "
                f"{significant(scores['commanded_residual_rate_rad_s'])} rad/s "
                f"({significant(scores['commanded_residual_rate_deg_s'])} deg/s), worst "
                f"{significant(scores['commanded_residual_rate_max_rad_s'])}"
                if scores.get("commanded_residual_rate_rad_s") is not None
                else ""
            )
            + (
                f"; >= 95 % of flights under {scores['final_rate_p95_rad_s']:.4f} rad/s "
                f"({scores['final_rate_p95_deg_s']:.3f} deg/s), 95 % conf."
                if scores.get("final_rate_p95_rad_s") is not None
                else ""
            )
            + f" | peak {scores['peak_rate_rad_s']:.4f} rad/s "
            + f"({scores['peak_rate_deg_s']:.2f} deg/s)"
            + (
                f" (>= 95 % of flights under {scores['peak_rate_p95_rad_s']:.4f} rad/s "
                f"({scores['peak_rate_p95_deg_s']:.2f} deg/s), 95 % conf.)"
                if scores.get("peak_rate_p95_rad_s") is not None
                else ""
            )
            # Three significant digits, as the dashboard: 0.45 N m s read 0.5 at :.1f.
            + f" | {scores['impulse_nms']:.3g} N m s{flags}",
            err=True,
        )
        confirmation = front.get("confirmation")
        if member["index"] == 0 and confirmation:
            # Member 0 is the best of every sequence measured on the front's series, so
            # its figure there is biased up on average: this one is not.
            click.echo(
                f"       again on {confirmation['test_series']} other series per candidate "
                "(the figure to quote; #0 is first on its own series): acc "
                + ", ".join(
                    f"{a:.3f} [{low:.3f}-{high:.3f}]"
                    for a, (low, high) in zip(
                        confirmation["accuracy_by_noise"],
                        confirmation["interval_by_noise"],
                        strict=True,
                    )
                ),
                err=True,
            )
            # The baselines that could dominate it, on the same series (its flags above
            # are judged there).
            for name, figures in (confirmation.get("baselines") or {}).items():
                click.echo(
                    f"       {name} on the same series: acc "
                    + "/".join(f"{a:.3f}" for a in figures["accuracy_by_noise"])
                    + (" (dominates #0)" if figures.get("dominates_member_0") else ""),
                    err=True,
                )
    for line in _rescore_cut(result.settings, front, result.fresh):
        click.echo(line, err=True)
    # The document records the scenario, so that `inertia-id plan --search` plans the
    # spacecraft the search ran on, not whatever --preset defaults to.
    write_output(out, json.dumps(outcome.to_dict()))
    click.echo(f"wrote {out}", err=True)
    click.echo(json.dumps(result.best.sequence))
