"""The ``inertia-id`` command line.

Every command takes a scenario (``--preset paper`` or ``--scenario FILE.json``) and a
seed; bad input ends with a one-line error naming the value, never a traceback.
"""

from __future__ import annotations

import functools
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click
import numpy as np

from ..classifiers.clustering import METRICS
from ..classifiers.registry import (
    CLASSIFIER_KINDS,
    default_realisations,
    load_classifier,
    parse_spec,
    resolve_kind,
    train,
    train_classifier,
)
from ..errors import InputError
from ..evaluation.identify import identify
from ..evaluation.sweep import DEFAULT_NOISES, NOISE_KINDS, run_inertia_sweep, run_sweep
from ..evaluation.telemetry import load_telemetry
from ..physics.presets import PRESETS, preset
from ..physics.scenario import Scenario
from ..physics.simulate import simulate
from ..search.baselines import compare_with_baselines

# The hand-designed excitation: the three positive-axis thrusters at full duty for
# every step. Used by `paper --search none`.
PAPER_DEFAULT_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4
DEFAULT_SEQUENCE_TEXT = ";".join(",".join(map(str, row)) for row in PAPER_DEFAULT_SEQUENCE)

F = TypeVar("F", bound=Callable[..., Any])


def _friendly_errors(func: F) -> F:
    """Turn the core's ValueErrors into one-line CLI errors."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (ValueError, OSError) as exc:
            raise click.ClickException(str(exc)) from None

    return wrapper  # type: ignore[return-value]


def _scenario_options(func: F) -> F:
    func = click.option(
        "--scenario",
        "scenario_path",
        type=click.Path(dir_okay=False),
        help="Scenario JSON file (overrides --preset).",
    )(func)
    func = click.option(
        "--preset",
        "preset_name",
        default="paper",
        show_default=True,
        type=click.Choice(sorted(PRESETS)),
        help="Built-in scenario.",
    )(func)
    return func


def _load_scenario(preset_name: str, scenario_path: str | None) -> Scenario:
    if scenario_path is None:
        return preset(preset_name)
    text = Path(scenario_path).read_text(encoding="utf-8")
    return Scenario.model_validate_json(text)


def parse_sequence(text: str) -> list[list[int]]:
    """A sequence from ``"4,4,4,0,0,0;0,0,0,4,4,4"`` (rows separated by ';'), a JSON
    list of rows, or a path to a JSON file holding one."""
    source = text
    if os.path.isfile(text):
        source = Path(text).read_text(encoding="utf-8")
    source = source.strip()
    try:
        if source.startswith("["):
            rows = json.loads(source)
        else:
            rows = [[int(v) for v in row.split(",")] for row in source.split(";") if row.strip()]
    except (ValueError, json.JSONDecodeError):
        raise InputError(
            f"sequence {text!r} is not rows of level indices like '4,4,4,0,0,0;0,0,0,4,4,4' "
            "or a JSON list of rows"
        ) from None
    if not isinstance(rows, list) or not rows:
        raise InputError(f"sequence {text!r} holds no steps")
    return rows


def _sequence_option(default: str | None = None) -> Callable[[F], F]:
    return click.option(
        "--sequence",
        "sequence_text",
        default=default,
        required=default is None,
        show_default=default is not None,
        help="Level indices per thruster, steps separated by ';' (e.g. '4,4,4,0,0,0;"
        "4,4,4,0,0,0'), a JSON list of rows, or a JSON file.",
    )


def _realisations_option(help_text: str) -> Callable[[F], F]:
    return click.option(
        "-n",
        "--realisations",
        default=20,
        show_default=True,
        type=click.IntRange(1),
        help=help_text,
    )


_multiples_option = click.option(
    "--multiples",
    default="1,2,3,4,5,6,7,8",
    show_default=True,
    help="Noise multiples of the training level, comma-separated.",
)
_n_test_option = click.option(
    "--n-test",
    default=200,
    show_default=True,
    type=click.IntRange(1),
    help="Test series per sweep point, spread over the candidates.",
)


def _seed_option(func: F) -> F:
    return click.option(
        "--seed", default=0, show_default=True, type=int, help="Seed of every random draw."
    )(func)


def _write_json(path: str | os.PathLike[str] | None, data: Any) -> None:
    text = json.dumps(data, indent=2)
    if path is None or str(path) == "-":
        click.echo(text)
    else:
        Path(path).write_text(text + "\n", encoding="utf-8")
        click.echo(f"wrote {path}", err=True)


def _progress_bar(total: int, desc: str) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="pt", file=sys.stderr, leave=False)


@click.group()
@click.version_option(package_name="inertia-id")
def main() -> None:
    """Tell which known inertia configuration a spacecraft is in, from its rate
    response to a deliberately chosen thruster sequence."""


@main.command("scenario")
@_scenario_options
@click.option("--out", type=click.Path(dir_okay=False), help="Write here instead of stdout.")
@_friendly_errors
def scenario_cmd(preset_name: str, scenario_path: str | None, out: str | None) -> None:
    """Print a scenario as JSON (a starting point to edit), after validating it."""
    scenario = _load_scenario(preset_name, scenario_path)
    _write_json(out, scenario.model_dump(mode="json"))


@main.command("simulate")
@_scenario_options
@_sequence_option(DEFAULT_SEQUENCE_TEXT)
@_realisations_option("Noisy realisations per candidate.")
@click.option(
    "--process-noise",
    default=1.0,
    show_default=True,
    type=click.FloatRange(0),
    help="Multiple of the scenario's disturbance torque.",
)
@click.option(
    "--measurement-noise",
    default=1.0,
    show_default=True,
    type=click.FloatRange(0),
    help="Multiple of the scenario's gyro noise.",
)
@_seed_option
@click.option(
    "--out", type=click.Path(dir_okay=False), help="Write every series: .npz (arrays) or .json."
)
@click.option(
    "--telemetry",
    type=click.Path(dir_okay=False),
    help="Write one series as telemetry CSV (time_s,wx,wy,wz) for `identify`.",
)
@click.option(
    "--candidate",
    default="0",
    show_default=True,
    help="Candidate (index or name) whose series --telemetry writes.",
)
@click.option(
    "--realisation",
    default=0,
    show_default=True,
    type=click.IntRange(0),
    help="Which realisation --telemetry writes.",
)
@_friendly_errors
def simulate_cmd(
    preset_name: str,
    scenario_path: str | None,
    sequence_text: str,
    realisations: int,
    process_noise: float,
    measurement_noise: float,
    seed: int,
    out: str | None,
    telemetry: str | None,
    candidate: str,
    realisation: int,
) -> None:
    """Simulate every candidate's gyro response to a sequence."""
    scenario = _load_scenario(preset_name, scenario_path)
    result = simulate(
        scenario,
        parse_sequence(sequence_text),
        realisations,
        np.random.default_rng(seed),
        process_noise_scale=process_noise,
        measurement_noise_scale=measurement_noise,
    )
    summary = {
        "candidates": result.candidate_names,
        "series_shape": list(result.omega_measured.shape),
        "impulse_nms": result.impulse_nms,
        "mean_final_rate_rad_s": result.mean_final_rate_rad_s,
        "final_rate_rad_s_per_candidate": result.final_rate_rad_s.mean(axis=1).tolist(),
    }
    if out:
        arrays = {
            "time_s": result.time_s,
            "omega_measured_rad_s": result.omega_measured,
            "omega_true_rad_s": result.omega_true,
            "applied_torque_nm": result.applied_torque_nm,
            "sequence": result.sequence,
        }
        if out.endswith(".npz"):
            np.savez_compressed(out, **arrays)  # type: ignore[arg-type]
        else:
            Path(out).write_text(
                json.dumps({**summary, **{k: v.tolist() for k, v in arrays.items()}}),
                encoding="utf-8",
            )
        click.echo(f"wrote {out}", err=True)
    if telemetry:
        k = _candidate_index(scenario, candidate)
        if realisation >= realisations:
            raise InputError(f"--realisation {realisation} but only {realisations} simulated")
        rows = np.column_stack([result.time_s, result.omega_measured[k, realisation]])
        np.savetxt(
            telemetry,
            rows,
            delimiter=",",
            header="time_s,wx_rad_s,wy_rad_s,wz_rad_s",
            comments="",
            fmt="%.10g",
        )
        click.echo(
            f"wrote {telemetry} ({scenario.candidate_names[k]}, realisation {realisation})",
            err=True,
        )
    _write_json(None, summary)


def _candidate_index(scenario: Scenario, candidate: str) -> int:
    names = scenario.candidate_names
    if candidate in names:
        return names.index(candidate)
    if candidate.isdigit() and int(candidate) < len(names):
        return int(candidate)
    raise InputError(
        f"candidate {candidate!r} is neither an index 0..{len(names) - 1} nor one of {names}"
    )


def _metric_option(func: F) -> F:
    return click.option(
        "--metric",
        default="dtw",
        show_default=True,
        type=click.Choice(METRICS),
        help="Clustering metric (dtw is the paper's; softdtw is slow).",
    )(func)


@main.command("train")
@_scenario_options
@_sequence_option(DEFAULT_SEQUENCE_TEXT)
@click.option(
    "--kind",
    default=None,
    type=click.Choice(CLASSIFIER_KINDS),
    help="marginal-likelihood (the default: closest to the limit), clustering (the paper's; "
    "the default when only --metric is given), nearest-centroid, 1nn, minirocket, "
    "likelihood or least-squares (the physics baseline).",
)
@click.option(
    "--metric",
    default=None,
    type=click.Choice(METRICS),
    help="clustering: dtw (default), softdtw or euclidean; nearest-centroid and 1nn: dtw "
    "(default) or euclidean; the other kinds take none.",
)
@click.option(
    "-n",
    "--realisations",
    default=None,
    type=click.IntRange(1),
    help="Training realisations per candidate [default: 100 for marginal-likelihood, else 20].",
)
@click.option(
    "--n-init",
    default=5,
    show_default=True,
    type=click.IntRange(1),
    help="clustering: k-means initialisations; the lowest-inertia one is kept.",
)
@click.option(
    "--band",
    default=None,
    type=click.IntRange(0),
    help="Sakoe-Chiba band half-width (samples) for dtw (clustering, nearest-centroid, "
    "1nn); default unconstrained.",
)
@_seed_option
@click.option(
    "--out",
    default="classifier.json",
    show_default=True,
    type=click.Path(dir_okay=False),
    help="Where to write the classifier JSON.",
)
@_friendly_errors
def train_cmd(
    preset_name: str,
    scenario_path: str | None,
    sequence_text: str,
    kind: str | None,
    metric: str | None,
    realisations: int | None,
    n_init: int,
    band: int | None,
    seed: int,
    out: str,
) -> None:
    """Train a classifier of any kind for a sequence at 1x noise."""
    scenario = _load_scenario(preset_name, scenario_path)
    sequence = parse_sequence(sequence_text)
    kind = resolve_kind(kind, metric)
    realisations = realisations or default_realisations(kind)
    options: dict[str, Any] = {}
    if kind in ("clustering", "nearest-centroid", "1nn"):
        options = {"metric": metric or "dtw", "sakoe_chiba_radius": band}
        if kind == "clustering":
            options["n_init"] = n_init
    elif metric is not None or band is not None:
        raise InputError(f"--kind {kind} takes no --metric or --band")
    click.echo(
        f"training {kind} {options.get('metric', '')} classifier on {scenario.n_candidates} "
        f"candidates x {realisations} realisations ...",
        err=True,
    )
    started = time.perf_counter()
    model = train_classifier(
        scenario, sequence, realisations, np.random.default_rng(seed), kind=kind, **options
    )
    model.save(out)
    click.echo(f"wrote {out} in {time.perf_counter() - started:.1f} s", err=True)
    _write_json(
        None,
        {
            "f1": model.f1_,
            "accuracy": model.accuracy_,
            "confusion": model.confusion_.tolist(),
            "candidates": model.candidate_names_,
        },
    )


def _parse_multiples(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise InputError(f"--multiples {text!r} is not a comma-separated list of numbers") from None
    return values


def _train_others(model: Any, specs: str, n_train: int, seed: int) -> dict[str, Any]:
    """The ``--others`` classifiers, trained at 1x on the model's scenario and sequence."""
    labels = [s.strip() for s in specs.split(",") if s.strip() and s.strip() != "none"]
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
    others = {}
    for label in labels:
        kind, options = parse_spec(label)
        others[label] = train_classifier(
            model.scenario_, model.sequence_, n_train, rng, kind=kind, **options
        )
    return others


@main.command("sweep")
@click.option(
    "--classifier",
    "classifier_path",
    required=True,
    type=click.Path(exists=True, dir_okay=False),
    help="Classifier JSON from `train` (any kind).",
)
@_multiples_option
@click.option(
    "--noise",
    "noises",
    multiple=True,
    type=click.Choice(NOISE_KINDS),
    help="Source of error to sweep (repeatable): process, measurement, jitter, thrust_scale, "
    "gyro_bias; default process and measurement.",
)
@click.option(
    "--others",
    default="least-squares",
    show_default=True,
    help="Classifiers trained at 1x and scored on the same test series, comma-separated "
    "specs (least-squares, 1nn:euclidean, nearest-centroid:dtw, minirocket, likelihood, "
    "clustering:euclidean), or 'none'.",
)
@click.option(
    "--limit-realisations",
    default=200,
    show_default=True,
    type=click.IntRange(0),
    help="The limit: a likelihood classifier fitted at each point's noise on this many "
    "realisations per candidate, scored on the same series (0: leave it out).",
)
@click.option(
    "--n-train",
    default=20,
    show_default=True,
    type=click.IntRange(3),
    help="Training realisations per candidate for --others.",
)
@click.option(
    "--inertia/--no-inertia",
    default=False,
    show_default=True,
    help="Also test bodies off the candidates (scaled, between the closest two): how often "
    "is 'matches none' the answer?",
)
@_n_test_option
@_seed_option
@click.option("--out", default="sweep.json", show_default=True, type=click.Path(dir_okay=False))
@_friendly_errors
def sweep_cmd(
    classifier_path: str,
    multiples: str,
    noises: tuple[str, ...],
    others: str,
    limit_realisations: int,
    n_train: int,
    inertia: bool,
    n_test: int,
    seed: int,
    out: str,
) -> None:
    """Accuracy of a trained classifier as each source of error grows, beside others."""
    model = load_classifier(classifier_path)
    noise_kinds = noises or DEFAULT_NOISES
    values = _parse_multiples(multiples)
    references = _train_others(model, others, n_train, seed)
    with _progress_bar(len(values) * len(noise_kinds), "sweep") as bar:
        result = run_sweep(
            model,
            others=references,
            limit_realisations=limit_realisations,
            multiples=values,
            noises=noise_kinds,
            n_test=n_test,
            seed=seed,
            progress=lambda _f: bar.update(1),
        )
    document = result.model_dump(mode="json")
    if inertia:
        document["inertia"] = run_inertia_sweep(model, seed=seed).model_dump(mode="json")
    _write_json(out, document)
    columns = {label: result.others[label] for label in references}
    if result.limit:
        columns["limit"] = result.limit
    click.echo(
        f"{'noise':12s} {'multiple':>8s} {'value':>9s}  accuracy [95 % interval]  "
        + "  ".join(columns)
    )
    for i, p in enumerate(result.points):
        rest = "  ".join(
            f"{points[i].accuracy:>{len(label)}.3f}" for label, points in columns.items()
        )
        click.echo(
            f"{p.noise:12s} {p.multiple:>8g} {p.value:>9.3g}  {p.accuracy:.3f} "
            f"[{p.ci_low:.3f}, {p.ci_high:.3f}]    {rest}"
        )
    if inertia:
        for q in document["inertia"]["points"]:
            click.echo(
                f"{q['body']:8s} {q['parameter']:>5g}  matches none {q['matches_none_rate']:.2f}"
            )


@main.command("identify")
@click.option(
    "--classifier",
    "classifier_path",
    required=True,
    type=click.Path(exists=True, dir_okay=False),
    help="Classifier JSON from `train`.",
)
@click.option(
    "--telemetry",
    "telemetry_path",
    required=True,
    type=click.Path(exists=True, dir_okay=False),
    help="CSV (time_s,wx,wy,wz; header optional) or JSON "
    "({time_s: [...], omega_rad_s: [[...], ...]}), time from the sequence start.",
)
@_friendly_errors
def identify_cmd(classifier_path: str, telemetry_path: str) -> None:
    """Classify telemetry to a candidate inertia, or say it matches none.

    The answer also holds the inertia tensor that integral-form least squares estimates
    from the same telemetry, and which parameters the sequence hardly excites.
    """
    model = load_classifier(classifier_path)
    verdict = identify(model, load_telemetry(telemetry_path))
    _write_json(None, verdict.model_dump(mode="json"))


def _parse_radius(text: str) -> int | None:
    if text.strip().lower() in ("none", "full", "unconstrained"):
        return None
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise InputError(f"--radius must be an integer >= 0 or 'none', got {text!r}")
    return value


def _parse_ppo_params(
    pairs: tuple[str, ...], option: str = "--ppo", example: str = "ent_coef=0.01"
) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip():
            raise InputError(f"{option} takes NAME=VALUE (e.g. {example}), got {pair!r}")
        try:
            number = float(value)
        except ValueError:
            raise InputError(f"{option} {name.strip()} must be a number, got {value!r}") from None
        params[name.strip()] = int(number) if number.is_integer() and "." not in value else number
    return params


def _search_options(func: F) -> F:
    options = [
        click.option(
            "--length",
            "sequence_length",
            default=4,
            show_default=True,
            type=click.IntRange(1, 50),
            help="Actuation steps L of the sequence.",
        ),
        click.option(
            "--timesteps",
            default=20_480,
            show_default=True,
            type=click.IntRange(1),
            help="Environment-step budget (ppo, random).",
        ),
        click.option(
            "--objective",
            default="f1",
            show_default=True,
            type=click.Choice(["f1", "separability"]),
            help="What scores a sequence: the clustering F1 (the paper's) or the "
            "Bhattacharyya separability bound (no clustering, much faster).",
        ),
        click.option(
            "--search-metric",
            "search_metric",
            default="dtw",
            show_default=True,
            type=click.Choice(["dtw", "euclidean", "softdtw"]),
            help="Clustering metric that scores sequences (dtw is the paper's).",
        ),
        click.option(
            "--radius",
            default="2",
            show_default=True,
            help="DTW Sakoe-Chiba band half-width in samples, or 'none'.",
        ),
        click.option(
            "--search-realisations",
            default=20,
            show_default=True,
            type=click.IntRange(1),
            help="Realisations per candidate in each environment step.",
        ),
        click.option(
            "--fuel-weight",
            default=0.0,
            show_default=True,
            type=click.FloatRange(0),
            help="Reward cost per N m s of commanded impulse.",
        ),
        click.option(
            "--patience",
            default=500,
            show_default=True,
            type=click.IntRange(1),
            help="ppo/cem/random: stop once F1 = 1 and no better sequence came for this many "
            "episodes.",
        ),
        click.option(
            "--cem",
            "cem_pairs",
            multiple=True,
            metavar="NAME=VALUE",
            help="Override a CEM setting (repeatable): population, elite_fraction, smoothing.",
        ),
        click.option(
            "--ppo",
            "ppo_pairs",
            multiple=True,
            metavar="NAME=VALUE",
            help="Override a PPO hyperparameter (repeatable), e.g. --ppo n_steps=1024.",
        ),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def _run_search(
    method: str,
    scenario: Scenario,
    *,
    seed: int,
    sequence_length: int,
    timesteps: int,
    search_metric: str,
    radius: str,
    search_realisations: int,
    fuel_weight: float,
    patience: int,
    ppo_pairs: tuple[str, ...],
    objective: str = "f1",
    cem_pairs: tuple[str, ...] = (),
    max_sequences: int = 100_000,
    policy_path: str | None = None,
) -> Any:
    from ..search import ScorerSettings, SearchProgress, search, space_size

    settings = ScorerSettings(
        n_realisations=search_realisations,
        metric=search_metric,
        sakoe_chiba_radius=_parse_radius(radius),
        objective=objective,
    )
    size = space_size(scenario, sequence_length)
    click.echo(
        f"searching ({method}) for a {sequence_length}-step sequence in a space of "
        f"({scenario.n_levels}^{scenario.n_thrusters})^{sequence_length} = {size:.4g} sequences",
        err=True,
    )
    options: dict[str, Any] = {
        "sequence_length": sequence_length,
        "fuel_weight": fuel_weight,
        "seed": seed,
        "settings": settings,
    }
    if method == "exhaustive":
        options["max_sequences"] = max_sequences
        total = size * sequence_length if size <= max_sequences else 1
    else:
        options["total_timesteps"] = timesteps
        options["patience_episodes"] = patience
        total = timesteps
    if method == "ppo":
        options["ppo_params"] = _parse_ppo_params(ppo_pairs)
        options["policy_path"] = policy_path
    elif ppo_pairs:
        raise InputError(f"--ppo applies to --method ppo only, not {method!r}")
    if method == "cem":
        options.update(_parse_ppo_params(cem_pairs, "--cem", "population=64"))
    elif cem_pairs:
        raise InputError(f"--cem applies to --method cem only, not {method!r}")
    with _progress_bar(total, method) as bar:
        bar.unit = "step"

        def progress(report: SearchProgress) -> None:
            bar.update(report.timesteps - bar.n)
            bar.set_postfix(
                reward=f"{report.point.mean_episode_reward:.3f}",
                best_f1=f"{report.point.best_f1:.3f}",
            )

        result = search(method, scenario, progress=progress, **options)
    click.echo(result.summary(), err=True)
    return result


@main.command("search")
@_scenario_options
@click.option(
    "--method",
    default="ppo",
    show_default=True,
    type=click.Choice(["ppo", "cem", "exhaustive", "random"]),
    help="PPO (the paper's), the cross-entropy method, exhaustive (small spaces) or random "
    "(the baseline).",
)
@_search_options
@click.option(
    "--max-sequences",
    default=100_000,
    show_default=True,
    type=click.IntRange(1),
    help="exhaustive: refuse spaces larger than this.",
)
@click.option(
    "--policy",
    "policy_path",
    type=click.Path(dir_okay=False),
    help="ppo: save the trained policy here (stable-baselines3 zip).",
)
@_seed_option
@click.option("--out", default="search.json", show_default=True, type=click.Path(dir_okay=False))
@_friendly_errors
def search_cmd(
    preset_name: str,
    scenario_path: str | None,
    method: str,
    out: str,
    **options: Any,
) -> None:
    """Find the actuation sequence that best separates the candidates.

    Writes the best sequence, its F1 on the search's noise draw and on fresh draws, its
    fuel and final rate, the learning curve, and the hand-designed baselines scored on
    the same fresh draws, as JSON.
    """
    from ..search import ScorerSettings

    scenario = _load_scenario(preset_name, scenario_path)
    result = _run_search(method, scenario, **options)
    document = json.loads(result.to_json())
    settings = ScorerSettings(
        n_realisations=options["search_realisations"],
        metric=options["search_metric"],
        sakoe_chiba_radius=_parse_radius(options["radius"]),
    )
    document["baselines"] = compare_with_baselines(
        scenario,
        len(result.best.sequence),
        settings,
        seed=result.fresh.seed,
        n_draws=len(result.fresh.f1),
    )
    click.echo(
        f"on the same fresh draws: found F1 {result.fresh.f1_mean:.3f}, "
        f"{result.best.fuel_nms:.1f} N m s, final rate {result.best.final_rate_rad_s:.3f} rad/s",
        err=True,
    )
    for name, base in document["baselines"].items():
        f1, rate = np.mean(base["fresh_f1"]), np.mean(base["fresh_final_rate_rad_s"])
        click.echo(
            f"  {name:14s} F1 {f1:.3f}, {base['fuel_nms']:.1f} N m s, final rate {rate:.3f} rad/s",
            err=True,
        )
    Path(out).write_text(json.dumps(document), encoding="utf-8")
    click.echo(f"wrote {out}", err=True)
    click.echo(json.dumps(result.best.sequence))


@main.command("paper")
@_sequence_option(None)
@click.option(
    "--search",
    "search_method",
    default="ppo",
    show_default=True,
    type=click.Choice(["ppo", "cem", "random", "none"]),
    help="How to find the sequence when --sequence is not given ('none': the "
    "hand-designed excitation).",
)
@_search_options
@_metric_option
@_realisations_option("Training realisations per candidate (the paper's 20).")
@_multiples_option
@_n_test_option
@_seed_option
@click.option(
    "--out-dir",
    default="results/paper",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Where results and report.html go.",
)
@_friendly_errors
def paper_cmd(
    sequence_text: str | None,
    search_method: str,
    metric: str,
    realisations: int,
    multiples: str,
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
    scenario = Scenario.paper()
    values = _parse_multiples(multiples)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    seeds = np.random.SeedSequence(seed).spawn(3)
    started = time.perf_counter()
    searched = None
    if sequence_text is not None:
        sequence = scenario.check_sequence(parse_sequence(sequence_text))
    elif search_method == "none":
        sequence = scenario.check_sequence(PAPER_DEFAULT_SEQUENCE)
    else:
        click.echo("[0/3] searching for the sequence", err=True)
        policy = str(out / "policy.zip") if search_method == "ppo" else None
        searched = _run_search(
            search_method, scenario, seed=seed, policy_path=policy, **search_options
        )
        (out / "search.json").write_text(searched.to_json(), encoding="utf-8")
        sequence = searched.best_sequence
    click.echo(
        f"[1/3] training {metric} classifier ({scenario.n_candidates} candidates x "
        f"{realisations} realisations, {len(sequence)} steps)",
        err=True,
    )
    model = train(scenario, sequence, realisations, np.random.default_rng(seeds[0]), metric=metric)
    model.save(out / "classifier.json")
    click.echo(f"      training F1 {model.f1_:.3f}, accuracy {model.accuracy_:.3f}", err=True)
    click.echo("[2/3] accuracy vs noise", err=True)
    references = _train_others(model, "least-squares", realisations, seed)
    with _progress_bar(2 * len(values), "sweep") as bar:
        sweep = run_sweep(
            model,
            others=references,
            limit_realisations=200,
            multiples=values,
            n_test=n_test,
            seed=int(seeds[1].generate_state(1)[0]),
            progress=lambda _f: bar.update(1),
        )
    (out / "sweep.json").write_text(sweep.model_dump_json(indent=2), encoding="utf-8")
    click.echo("[3/3] report", err=True)
    result = simulate(scenario, sequence, realisations, np.random.default_rng(seeds[2]))
    from ..evaluation.report import write_report

    write_report(
        out / "report.html",
        scenario=scenario,
        sequence=sequence,
        result=result,
        classifier=model,
        sweep=sweep,
        search=searched,
    )
    (out / "scenario.json").write_text(scenario.model_dump_json(indent=2), encoding="utf-8")
    summary = {
        "sequence": sequence.tolist(),
        "sequence_from": "given" if searched is None else f"{searched.method} search",
        "search_f1": None if searched is None else searched.best.f1,
        "search_fresh_f1_mean": None if searched is None else searched.fresh.f1_mean,
        "search_timesteps": None if searched is None else searched.timesteps,
        "metric": metric,
        "seed": seed,
        "training_f1": model.f1_,
        "training_accuracy": model.accuracy_,
        "impulse_nms": result.impulse_nms,
        "mean_final_rate_rad_s": result.mean_final_rate_rad_s,
        "accuracy": {
            noise: {f"{p.multiple:g}": p.accuracy for p in sweep.curve(noise)}
            for noise in DEFAULT_NOISES
        },
        "accuracy_others": {
            label: {
                noise: {f"{p.multiple:g}": p.accuracy for p in points if p.noise == noise}
                for noise in DEFAULT_NOISES
            }
            for label, points in {**sweep.others, "limit": sweep.limit}.items()
        },
        "wall_time_s": time.perf_counter() - started,
    }
    _write_json(out / "summary.json", summary)
    click.echo(
        f"training F1 {model.f1_:.3f}; accuracy at x{values[-1]:g}: process "
        f"{sweep.curve('process')[-1].accuracy:.3f}, measurement "
        f"{sweep.curve('measurement')[-1].accuracy:.3f}"
    )
    click.echo(f"report: {out / 'report.html'}")


@main.command(
    "serve",
    add_help_option=False,
    context_settings={"ignore_unknown_options": True, "allow_extra_args": True},
)
@click.argument("serve_args", nargs=-1, type=click.UNPROCESSED)
def serve_cmd(serve_args: tuple[str, ...]) -> None:
    """Run the web service and its workers on this machine (--host, --port, --data-dir,
    --workers; see `inertia-id serve --help`)."""
    # The core imports nothing from the service: hand over to `python -m app.serve`, which
    # parses (and documents) the options.
    os.execv(sys.executable, [sys.executable, "-m", "app.serve", *serve_args])


if __name__ == "__main__":
    main()
