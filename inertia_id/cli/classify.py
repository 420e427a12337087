"""``inertia-id train``, ``sweep`` and ``identify``: classifiers, their accuracy against
noise, and verdicts on telemetry."""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from typing import Any

import click

from ..pipelines import SweepRequest
from ..wording import counted
from .options import (
    DEFAULT_SEQUENCE_TEXT,
    FloatRange,
    IntRange,
    LazyChoice,
    classifier_option,
    friendly_errors,
    load_scenario,
    multiples_option,
    n_test_option,
    one_line,
    out_option,
    parse_multiples,
    parse_sequence,
    progress_bar,
    realisations_option,
    refuse_past_memory,
    scenario_options,
    seed_option,
    sequence_option,
    time_limit_option,
    write_json,
)

__all__ = ["identify_cmd", "sweep_cmd", "train_cmd"]


def _kinds() -> tuple[str, ...]:
    from ..classifiers.registry import CLASSIFIER_KINDS

    return CLASSIFIER_KINDS


def _metrics() -> list[str]:
    from ..classifiers.registry import CLASSIFIER_KINDS, kind_metrics

    return list(dict.fromkeys(m for kind in CLASSIFIER_KINDS for m in kind_metrics(kind)))


def _noises() -> tuple[str, ...]:
    from ..evaluation.sweep import NOISE_KINDS

    return NOISE_KINDS


@click.command("train")
@scenario_options
@sequence_option(DEFAULT_SEQUENCE_TEXT)
@click.option(
    "--kind",
    default=None,
    type=LazyChoice(_kinds),
    help="marginal-likelihood (the default: closest to the sweeps' ceiling, at most 3 points "
    "short in bench/classifier_ceiling.py), clustering (the paper's; "
    "the default when only --metric is given), nearest-centroid, 1nn, minirocket, "
    "likelihood or least-squares (the physics baseline).",
)
@click.option(
    "--metric",
    default=None,
    type=LazyChoice(_metrics),
    help="clustering: dtw (default), softdtw or euclidean; nearest-centroid and 1nn: dtw "
    "(default) or euclidean; the other kinds take none.",
)
@realisations_option(
    "Training realisations per candidate [default: 100 for marginal-likelihood, else 20].",
    default=None,
)
@click.option(
    "--n-init",
    default=None,
    type=IntRange(1),
    help="clustering: k-means initialisations; the lowest-inertia one is kept [default: 5].",
)
@click.option(
    "--band",
    default=None,
    type=IntRange(0),
    help="Sakoe-Chiba band half-width (samples) for dtw (clustering, nearest-centroid, "
    "1nn); default unconstrained.",
)
@time_limit_option(
    "Stop the training after this many seconds (wall clock), at its next checkpoint "
    "(after a simulation, between the pieces of a fit), and write nothing; none by default."
)
@seed_option
@out_option("classifier.json", "Where to write the classifier JSON.")
@friendly_errors
def train_cmd(
    preset_name: str,
    scenario_path: str | None,
    sequence_text: str,
    kind: str | None,
    metric: str | None,
    realisations: int | None,
    n_init: int | None,
    band: int | None,
    time_limit_s: float | None,
    seed: int,
    out: str,
) -> None:
    """Train a classifier of any kind for a sequence at 1x noise."""
    from ..classifiers.registry import (
        check_document_size,
        kind_class,
        kind_metrics,
        resolve_kind,
    )
    from ..deadline import Deadline
    from ..errors import InputError
    from ..pipelines import TrainRequest, train_for_sequence
    from ..stopping import TrainingStopped

    scenario = load_scenario(preset_name, scenario_path)
    resolved = resolve_kind(kind, metric)
    if not kind_metrics(resolved) and (metric is not None or band is not None):
        raise InputError(f"--kind {resolved} takes no --metric or --band")
    request = TrainRequest(
        parse_sequence(sequence_text, scenario),
        kind=resolved,
        metric=metric,
        n_realisations=realisations,
        sakoe_chiba_radius=band,
        n_init=n_init,
    )
    kind, n_realisations, options = request.resolved()
    # As the API's train job: in the option's words, before anything is simulated (the
    # classifier's own check came after the training's line and named its labels, y).
    least = kind_class(kind).MIN_REALISATIONS
    if n_realisations < least:
        raise InputError(
            f"-n {n_realisations}: the {kind!r} classifier needs at least {least} "
            "realisations per candidate"
        )
    scenario.check_fires(request.sequence)
    # A classifier that identify --classifier would refuse to load is not trained.
    check_document_size(kind, scenario, len(request.sequence), n_realisations)
    # The training series alone; a classifier's features come on top of them.
    refuse_past_memory(
        f"-n {n_realisations}",
        candidates=scenario.n_candidates,
        realisations=n_realisations,
        samples=len(request.sequence) * scenario.timing.samples_per_step,
    )
    # A kind without a metric left two spaces where the metric goes.
    described = " ".join(filter(None, (kind, options.get("metric"))))
    click.echo(
        f"training {described} classifier on {scenario.n_candidates} "
        f"candidates x {counted(n_realisations, 'realisation')} ...",
        err=True,
    )
    started = time.perf_counter()
    # As a train job's limit: read at the training's checkpoints, so it ends part-way
    # and nothing half-trained is written. A training that finished is written, even
    # if its last piece ran past the limit: it is whole.
    deadline = Deadline(time_limit_s)
    try:
        trained = train_for_sequence(scenario, request, seed=seed, should_stop=deadline.expired)
    except TrainingStopped:
        raise click.ClickException(
            f"the training reached its time limit of {time_limit_s:g} s (--time-limit) "
            f"after {time.perf_counter() - started:.1f} s and stopped part-way; "
            f"nothing written to {out}"
        ) from None
    trained.model.save(out)
    click.echo(f"wrote {out} in {time.perf_counter() - started:.1f} s", err=True)
    summary = trained.summary()
    for warning in trained.warnings:
        click.echo(f"warning: {warning}", err=True)
    write_json(
        None,
        {
            "f1": summary["f1"],
            "accuracy": summary["accuracy"],
            "confusion": summary["confusion"],
            "candidates": summary["candidate_names"],
            "warnings": summary["warnings"],
        },
    )


@click.command("sweep")
@classifier_option("Classifier JSON from `train` (any kind).")
@multiples_option
@click.option(
    "--noise",
    "noises",
    multiple=True,
    type=LazyChoice(_noises),
    help="Source of error to sweep (repeatable): process, measurement, jitter, thrust_scale, "
    "gyro_bias; default process and measurement.",
)
@click.option(
    "--others",
    default=",".join(SweepRequest.default("others")),
    show_default=True,
    help="Classifiers trained at 1x and scored on the same test series, comma-separated "
    "specs (least-squares, 1nn:euclidean, nearest-centroid:dtw, minirocket, likelihood, "
    "clustering:euclidean), or 'none'.",
)
@click.option(
    "--ceiling-realisations",
    default=SweepRequest.default("ceiling_realisations"),
    show_default=True,
    type=IntRange(0),
    help="The ceiling: per-candidate Gaussians fitted at each point's noise on this many "
    "realisations per candidate, scored on the same series (0: leave it out).",
)
@click.option(
    "--limit-realisations",
    default=None,
    type=IntRange(0),
    help="Deprecated name of --ceiling-realisations.",
)
@click.option(
    "--n-train",
    default=SweepRequest.default("n_train"),
    show_default=True,
    type=IntRange(3),
    help="Training realisations per candidate for --others.",
)
@click.option(
    "--inertia/--no-inertia",
    default=SweepRequest.default("inertia"),
    show_default=True,
    help="Also test bodies off the candidates (scaled, between the closest two): how often "
    "is 'matches none' the answer?",
)
@n_test_option(SweepRequest.default("n_test"))
@seed_option
@out_option("sweep.json", "Where to write the sweep JSON.")
@friendly_errors
def sweep_cmd(
    classifier_path: str,
    multiples: str | None,
    noises: tuple[str, ...],
    others: str,
    ceiling_realisations: int,
    limit_realisations: int | None,
    n_train: int,
    inertia: bool,
    n_test: int,
    seed: int,
    out: str,
) -> None:
    """Accuracy of a trained classifier as each source of error grows, beside others."""
    from ..classifiers.registry import load_classifier
    from ..errors import InputError
    from ..pipelines import sweep_with_limit

    other_specs = tuple(s.strip() for s in others.split(",") if s.strip())
    if not other_specs:
        # An empty list meant 'none' without saying so; a misquoted shell variable reads so.
        raise InputError(f"--others names none, got {others!r}: give specs, or 'none'")
    model = load_classifier(classifier_path)
    if model.scenario_ is not None and model.sequence_ is not None:
        # The largest simulation a sweep runs at once: a point's test series (--n-test
        # spread over the candidates) or the others' training series (--n-train).
        k = model.scenario_.n_candidates
        refuse_past_memory(
            f"--n-test {n_test}, --n-train {n_train}",
            candidates=k,
            realisations=max(n_test // k, n_train if set(other_specs) - {"none"} else 0),
            samples=len(model.sequence_) * model.scenario_.timing.samples_per_step,
        )
        if n_test >= k and n_test % k:
            # The sweep draws whole series a candidate: the rest was dropped without a word.
            click.echo(
                f"warning: --n-test {n_test} over {k} candidates draws {n_test // k} series "
                f"a candidate, {n_test // k * k} a point",
                err=True,
            )
    request = SweepRequest(
        multiples=parse_multiples(multiples),
        noises=noises or None,
        others=tuple(s for s in other_specs if s != "none"),
        ceiling_realisations=ceiling_realisations,
        limit_realisations=limit_realisations,
        n_train=n_train,
        inertia=inertia,
        n_test=n_test,
    )
    with progress_bar(100, "sweep", unit="%") as bar:
        outcome = sweep_with_limit(
            model, request, seed=seed, progress=lambda f: bar.update(round(100 * f) - bar.n)
        )
    document = outcome.to_dict()
    write_json(out, document)
    result = outcome.sweep
    columns = {label: result.others[label] for label in outcome.others}
    if result.ceiling:
        columns["ceiling"] = result.ceiling
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
    if outcome.inertia is not None:
        for q in outcome.inertia.points:
            verdicts = (
                ""
                if q.identified_right_rate is None
                else f"  identified right {q.identified_right_rate:.2f}, wrong "
                f"{q.identified_wrong_rate:.2f}, ambiguous {q.ambiguous_rate:.2f}"
            )
            click.echo(
                f"{q.body:8s} {q.parameter:>5g}  matches none {q.matches_none_rate:.2f}{verdicts}"
            )


@click.command("identify")
@classifier_option("Classifier JSON from `train`.")
@click.argument("inputs", nargs=-1, type=click.Path(exists=True, file_okay=True, dir_okay=True))
@click.option(
    "--telemetry",
    "telemetry_paths",
    multiple=True,
    type=click.Path(exists=True, dir_okay=True),
    help="Telemetry file or folder (repeatable; paths may also follow the options). CSV "
    "(time_s or time_utc, wx, wy, wz; header optional) or JSON ({time_s or time_utc: [...], "
    "omega_rad_s: [[...], ...], sequence_start: ...}; omega_deg_s for deg/s), either "
    "gzip-compressed or not "
    "(pass.csv.gz). A folder gives its *.csv, *.json, *.csv.gz and *.json.gz.",
)
@click.option(
    "--sequence-start",
    default=None,
    help="Start of the actuation sequence in the telemetry's clock: seconds (e.g. mission "
    "time) or ISO-8601 UTC (2025-03-01T12:00:00Z); overrides a JSON file's. Needed unless "
    "the stamps are seconds from the sequence start.",
)
@click.option(
    "--estimate-start-within",
    "start_window_s",
    default=None,
    type=FloatRange(0),
    help="Search start times within this many seconds of the given start, one grid period "
    "apart, for the one whose series is closest to a candidate; the likelihood kinds then "
    "refine it below the grid period (scoring the starts between the grid's on a coarse "
    "grid, such as 1 Hz). The shift is reported.",
)
@click.option(
    "--pre-start-window",
    "pre_start_window_s",
    default=None,
    type=FloatRange(0),
    help="Seconds of telemetry before the sequence start that measure the body's rate plus "
    "the gyro bias there and the noise level; the default classifier conditions on them "
    "[default: 30; 0 ignores them].",
)
@click.option(
    "--averaged-gyro",
    "averaged",
    is_flag=True,
    help="Each rate is the mean over one sample period (the median spacing) before its "
    "stamp (an integrating or delta-angle gyro): read it half a period earlier. Without "
    "it a rate is read as instantaneous at its stamp.",
)
@friendly_errors
def identify_cmd(
    classifier_path: str,
    inputs: tuple[str, ...],
    telemetry_paths: tuple[str, ...],
    sequence_start: str | None,
    start_window_s: float | None,
    pre_start_window_s: float | None,
    averaged: bool,
) -> None:
    """Classify telemetry to a candidate inertia, or say it matches none.

    The answer also holds the inertia tensor that integral-form least squares estimates
    from the same telemetry, and which parameters the sequence hardly excites.

    Every verdict names its classifier: ``classifier_id`` (the service's id, from the
    file's provenance; null for a file without one, such as ``train`` writes) and
    ``classifier`` (the file as given, the sha256 its document states over its payload,
    and its provenance).

    One file: its verdict as indented JSON, and a bad file is an error. Several files or a
    folder: one JSON line per file, {"path": ..., verdict...} or {"path": ..., "error":
    ...}; every file is tried, and the exit code is 1 if any failed.
    """
    from pydantic import ValidationError

    from ..classifiers.registry import load_classifier_identified
    from ..errors import InputError
    from ..evaluation.telemetry import parse_sequence_start

    for option, seconds in (
        ("--estimate-start-within", start_window_s),
        ("--pre-start-window", pre_start_window_s),
    ):
        # Once, before any file: nan was refused per file, by the core's name
        # (estimate_start_within_s, pre_start_window_s).
        if seconds is not None and not math.isfinite(seconds):
            raise InputError(f"{option} {seconds:g}: give a finite number of seconds >= 0")
    paths = _telemetry_files((*telemetry_paths, *inputs))
    start = parse_sequence_start(sequence_start, "--sequence-start")
    classifier, identity = load_classifier_identified(classifier_path)
    # Which classifier judged, as the API's verdict names it (classifier_id): a verdict
    # kept from the CLI said nothing of the classifier (hostile review).
    provenance = identity["provenance"] or {}
    named = {"classifier_id": provenance.get("classifier_id"), "classifier": identity}
    options: dict[str, Any] = {}
    if pre_start_window_s is not None:
        options["pre_start_window_s"] = pre_start_window_s
    if len(paths) == 1 and not any(os.path.isdir(p) for p in (*telemetry_paths, *inputs)):
        verdict = _identify_file(classifier, paths[0], start, start_window_s, options, averaged)
        write_json(None, {**named, **verdict})
        _warn_untested([verdict])
        return
    failed = 0
    judged: list[dict[str, Any]] = []
    for path in paths:
        try:
            verdict = _identify_file(classifier, path, start, start_window_s, options, averaged)
            judged.append(verdict)
            line = {"path": path, **named, **verdict}
        except (InputError, ValidationError, OSError, UnicodeDecodeError) as exc:
            failed += 1
            line = {"path": path, "error": one_line(exc)}
        click.echo(json.dumps(line))
    _warn_untested(judged)
    if failed:
        click.echo(f"{failed} of {len(paths)} telemetry files failed", err=True)
        raise SystemExit(1)


#: The names a folder's telemetry files end with.
_TELEMETRY_SUFFIXES = (".csv", ".json", ".csv.gz", ".json.gz")


def _telemetry_files(given: tuple[str, ...]) -> list[str]:
    from ..errors import InputError

    if not given:
        raise InputError("give telemetry: --telemetry PATH or paths after the options")
    paths: list[str] = []
    for entry in given:
        if os.path.isdir(entry):
            # Regular files only: a named pipe would be waited on for good.
            found = sorted(
                str(p)
                for p in Path(entry).iterdir()
                if p.name.lower().endswith(_TELEMETRY_SUFFIXES) and p.is_file()
            )
            if not found:
                raise InputError(
                    f"folder {entry!r} holds no .csv or .json telemetry (nor .csv.gz, .json.gz)"
                )
            paths += found
        else:
            paths.append(entry)
    return list(dict.fromkeys(paths))


def _identify_file(
    classifier: Any,
    path: str,
    start: float | str | None,
    window_s: float | None,
    options: dict[str, Any],
    averaged: bool = False,
) -> dict[str, Any]:
    from ..evaluation.identify import identify
    from ..evaluation.telemetry import load_telemetry

    telemetry = load_telemetry(path, sequence_start=start, averaged=averaged)
    verdict = identify(classifier, telemetry, estimate_start_within_s=window_s, **options)
    if window_s is not None and verdict.sequence_start_shifts_tried_s is not None:
        grid = classifier.scenario_.sample_times(len(classifier.sequence_))
        step = float(grid[1] - grid[0])
        searched = verdict.sequence_start_shifts_tried_s
        if searched[0] > -window_s + step or searched[1] < window_s - step:
            # Starts the telemetry does not cover were skipped: say so, not a quiet answer
            # from a narrower window than the one asked for (helper-22's review).
            t = telemetry.time_array
            click.echo(
                f"warning: {path}: only starts {searched[0]:+.6g} s to {searched[1]:+.6g} s "
                f"from the stated one could be tried, not ±{window_s:g} s: the telemetry "
                f"covers {t[0]:.6g} s to {t[-1]:.6g} s from the stated start and the sequence "
                f"lasts {grid[-1]:.6g} s; telemetry from before the start to after the end "
                "searches the whole window",
                err=True,
            )
        if verdict.sequence_start_note:
            # The kind compares whole series: its start is the grid start its distance
            # favours, not refined (README *Start below the grid period*); said beside the
            # JSON as the verdict's sequence_start_note says it, not only by the false
            # sequence_start_refined.
            click.echo(f"warning: {path}: {verdict.sequence_start_note}", err=True)
        if verdict.start_window_hint:
            # Whatever the status: an identified verdict from a start at the window's
            # edge, with a better one beyond it, is said to be so beside the JSON.
            click.echo(f"warning: {path}: {verdict.start_window_hint}", err=True)
    if verdict.pre_start_activity_hint:
        # Whatever the status (an identified verdict's text is its name): said beside the
        # JSON, as its pre_start_activity_hint says it.
        click.echo(f"warning: {path}: {verdict.pre_start_activity_hint}", err=True)
    return verdict.model_dump(mode="json")


def _warn_untested(verdicts: list[dict[str, Any]]) -> None:
    """Once a run, on stderr: the identified verdicts whose classifier cannot test for
    bodies off the candidates (their names are the posterior's alone), said beside the
    JSON, not only in a field of each verdict."""
    named = [v for v in verdicts if v.get("status") == "identified"]
    notes = [v["off_candidates_note"] for v in named if v.get("off_candidates_note")]
    if notes:
        which = "" if len(verdicts) == 1 else f" ({counted(len(notes), 'identified verdict')})"
        click.echo(f"warning{which}: {notes[0]}", err=True)
