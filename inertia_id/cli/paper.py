"""``inertia-id paper``: the paper's pipeline from the command line."""

from __future__ import annotations

from typing import Any

import click

from ..errors import InputError
from ..pipelines import SweepRequest
from .options import (
    LazyChoice,
    friendly_errors,
    multiples_option,
    n_test_option,
    out_option,
    parse_multiples,
    parse_sequence,
    progress_bar,
    realisations_option,
    seed_option,
    sequence_option,
)
from .search import search_options, search_request

__all__ = ["paper_cmd"]


def _searches() -> list[str]:
    from ..search import SEARCH_METHODS

    # Exhaustive search cannot cover the paper's space: (5^6)^4 sequences.
    return [method for method in SEARCH_METHODS if method != "exhaustive"] + ["none"]


def _metrics() -> tuple[str, ...]:
    from ..classifiers.registry import kind_metrics

    return kind_metrics("clustering")


@click.command("paper")
@sequence_option(None, when_omitted="Optional: without it, one is searched for (--search).")
@click.option(
    "--search",
    "search_method",
    default="ppo",
    show_default=True,
    type=LazyChoice(_searches),
    help="How to find the sequence when --sequence is not given: ppo (the paper's), cem, "
    "random, or none (the hand-designed excitation).",
)
@search_options
@click.option(
    "--metric",
    default="dtw",
    show_default=True,
    type=LazyChoice(_metrics),
    help="Clustering metric: dtw (the paper's), euclidean, or softdtw (slow).",
)
@realisations_option("Training realisations per candidate (the paper's 20).")
@multiples_option
@n_test_option(SweepRequest.default("n_test"))
@seed_option
@out_option("results/paper", "Where results and report.html go.", folder=True)
@friendly_errors
def paper_cmd(
    sequence_text: str | None,
    search_method: str,
    metric: str,
    realisations: int,
    multiples: str | None,
    n_test: int,
    seed: int,
    out_dir: str,
    **search_options: Any,
) -> None:
    """The paper's pipeline on its preset: search, train, sweep, report.

    Without --sequence, a sequence is searched for first (PPO by default, stopping once
    it has F1 = 1 and nothing better turned up for --patience episodes); --search none
    uses the hand-designed excitation (the three positive-axis thrusters at full duty
    every step).
    """
    from ..physics.scenario import Scenario
    from ..pipelines import run_paper
    from ..search import SearchProgress

    search = None
    if sequence_text is None and search_method != "none":
        search = search_request(search_method, **search_options)
    else:
        # Search settings given with no search to apply them to are a mistake to say.
        context = click.get_current_context()
        given = [
            name
            for name in search_options
            if context.get_parameter_source(name) is click.core.ParameterSource.COMMANDLINE
        ]
        if given:
            why = "--sequence is given" if sequence_text is not None else "--search is none"
            flags = {param.name: param.opts[0] for param in context.command.params}
            options = ", ".join(flags.get(name, name) for name in given)
            raise InputError(f"{options}: search settings, but no search runs ({why})")
    bars: list[Any] = []

    def search_progress(report: SearchProgress) -> None:
        if not bars:
            bars.append(progress_bar(report.total_timesteps, search_method, unit="step"))
        bars[-1].update(report.timesteps - bars[-1].n)

    def sweep_progress(fraction: float) -> None:
        if len(bars) < 2:
            if bars:
                bars[-1].close()
            bars.append(progress_bar(100, "sweep", unit="%"))
        bars[-1].update(round(100 * fraction) - bars[-1].n)

    try:
        outcome = run_paper(
            out_dir,
            sequence=(
                None
                if sequence_text is None
                else parse_sequence(sequence_text, Scenario.paper())  # a plan's duties on it
            ),
            search=search,
            metric=metric,
            n_realisations=realisations,
            multiples=parse_multiples(multiples),
            n_test=n_test,
            seed=seed,
            log=lambda message: click.echo(message, err=True),
            search_progress=search_progress,
            sweep_progress=sweep_progress,
        )
    finally:
        for bar in bars:
            bar.close()
    summary, sweep = outcome.summary, outcome.sweep
    process, measurement = sweep.curve("process")[-1], sweep.curve("measurement")[-1]
    click.echo(
        f"training F1 {summary['training_f1']:.3f}; accuracy at x{process.multiple:g}: process "
        f"{process.accuracy:.3f}, measurement {measurement.accuracy:.3f}"
    )
    click.echo(f"report: {outcome.out_dir / 'report.html'}")
