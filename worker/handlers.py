"""What each job type does: a thin layer from a job's params to an ``inertia_id`` call.

Imported only inside the task process: it pulls in torch, numba and tslearn. Parameter
names are the ones the API validates and stores in ``JobRow.params`` (with defaults
filled); a name left out falls back to the core's default.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from typing import Any

import numpy as np

from app.db import ClassifierRow
from app.db.models import new_id
from inertia_id import (
    InputError,
    Scenario,
    classifier_from_json,
    run_inertia_sweep,
    run_sweep,
    train_classifier,
)
from inertia_id.classifiers.registry import default_realisations, parse_spec, resolve_kind
from inertia_id.search import ScorerSettings, SearchProgress, search
from inertia_id.search.baselines import compare_with_baselines

from .runner import JobContext, Outcome

__all__ = ["HANDLERS", "run_search_job", "run_sweep_job", "run_train_job"]

#: The metric keys a search writes after every rollout (PPO) or report (random,
#: exhaustive), at step = environment steps so far.
SEARCH_METRICS = ("mean_episode_reward", "mean_f1", "best_f1", "best_final_rate_rad_s")


def _present(params: dict[str, Any], names: dict[str, str]) -> dict[str, Any]:
    """``{core_name: params[job_name]}`` for the job names present in ``params``."""
    return {core: params[job] for job, core in names.items() if job in params}


def run_search_job(context: JobContext) -> Outcome:
    """Search for the actuation sequence (ppo, exhaustive or random).

    Metrics: :data:`SEARCH_METRICS` at step = timesteps, after every curve point.
    A PPO policy is saved to ``data_dir/policies/<job id>.zip`` and its path and
    SHA-256 put in the result.
    """
    spec = context.spec
    params = spec.params
    method = params.get("method", "ppo")
    scenario = Scenario.model_validate(spec.scenario)
    scorer = ScorerSettings(
        **_present(
            params,
            {
                "n_realisations": "n_realisations",
                "objective": "objective",
                "metric": "metric",
                "sakoe_chiba_radius": "sakoe_chiba_radius",
            },
        )
    )
    options: dict[str, Any] = _present(
        params, {"sequence_length": "sequence_length", "fuel_weight": "fuel_weight"}
    )
    if method == "exhaustive":
        options.update(_present(params, {"max_sequences": "max_sequences"}))
    else:
        options.update(
            _present(
                params,
                {"timesteps": "total_timesteps", "patience_episodes": "patience_episodes"},
            )
        )
    if method == "cem":
        options.update(params.get("cem") or {})
    policy_path = None
    if method == "ppo":
        options["ppo_params"] = params.get("ppo") or {}
        policy_path = context.data_dir / "policies" / f"{spec.id}.zip"
        policy_path.parent.mkdir(parents=True, exist_ok=True)
        options["policy_path"] = str(policy_path)

    def progress(report: SearchProgress) -> None:
        point = report.point
        context.report(
            progress=report.fraction,
            metrics=[(key, report.timesteps, getattr(point, key)) for key in SEARCH_METRICS],
        )

    found = search(
        method,
        scenario,
        seed=spec.seed,
        settings=scorer,
        progress=progress,
        should_stop=context.should_stop,
        **options,
    )
    result = json.loads(found.to_json())
    # The baselines on the very draws the best sequence was re-scored on: what the
    # search adds (or not) over a hand-designed excitation.
    result["baselines"] = compare_with_baselines(
        scenario,
        len(found.best.sequence),
        scorer,
        seed=found.fresh.seed,
        n_draws=len(found.fresh.f1),
    )
    if found.policy_path is not None:
        with open(found.policy_path, "rb") as fh:
            result["policy_sha256"] = hashlib.sha256(fh.read()).hexdigest()
    status = "cancelled" if found.stopped == "cancelled" else "succeeded"
    return Outcome(status=status, result=result)


def run_train_job(context: JobContext) -> Outcome:
    """Train the classifier for a sequence and store it as a ``classifiers`` row.

    The k-means seed and the training draws come from the job's seed. Metrics: "f1" and
    "accuracy" at step 0.
    """
    spec = context.spec
    params = spec.params
    scenario = Scenario.model_validate(spec.scenario)
    kind = resolve_kind(params.get("kind"), params.get("metric"))
    n_realisations = int(params.get("n_realisations") or default_realisations(kind))
    options = {"metric": params["metric"]} if params.get("metric") is not None else {}
    model = train_classifier(
        scenario,
        params["sequence"],
        n_realisations,
        np.random.default_rng(spec.seed),
        kind=kind,
        **options,
    )
    if context.check_now():
        return Outcome(status="cancelled", result=None)
    document = model.to_json()
    checksum = json.loads(document).get("sha256") or hashlib.sha256(document.encode()).hexdigest()
    sequence = np.asarray(model.sequence_).tolist()
    confusion = np.asarray(model.confusion_).tolist()
    row = ClassifierRow(
        id=new_id(),
        job_id=spec.id,
        scenario_id=spec.scenario_id,
        kind=kind,
        metric=model.metric,
        f1=float(model.f1_),
        accuracy=float(model.accuracy_),
        sequence=sequence,
        candidate_names=list(model.candidate_names_),
        confusion=confusion,
        document=document,
        sha256=checksum,
    )
    result = {
        "classifier_id": row.id,
        "kind": kind,
        "metric": row.metric,
        "f1": row.f1,
        "accuracy": row.accuracy,
        "confusion": confusion,
        "candidate_names": row.candidate_names,
        "sequence": sequence,
        "n_realisations": n_realisations,
        "sha256": checksum,
    }
    return Outcome(
        status="succeeded",
        result=result,
        metrics=[("f1", 0, row.f1), ("accuracy", 0, row.accuracy)],
        rows=[row],
    )


def run_sweep_job(context: JobContext) -> Outcome:
    """Accuracy of a stored classifier as each source of error grows.

    ``others`` (default: least squares) are trained at 1x on the classifier's scenario
    and sequence, from the job's seed, and scored on the same test series, and so is the
    limit (a likelihood classifier fitted at each point's noise, ``limit_realisations``
    per candidate); with ``inertia`` the result also says how often bodies off the
    candidates are flagged "matches none". Metrics: "accuracy_<noise>" for each noise
    swept, one point per multiple, at step = the multiple's index in the job's
    ``multiples`` list (0, 1, ...), value = the accuracy there. A cancel stops between
    points; the points done are kept.
    """
    spec = context.spec
    params = spec.params
    classifier_id = params.get("classifier_id")
    with context.db.session() as session:
        row = session.get(ClassifierRow, classifier_id) if classifier_id else None
        document = None if row is None else row.document
    if document is None:
        raise InputError(f"classifier {classifier_id!r} does not exist")
    classifier = classifier_from_json(document)
    scenario = classifier.scenario_
    if scenario is None:
        raise InputError(f"classifier {classifier_id!r} does not carry its scenario")
    seeds = np.random.SeedSequence(spec.seed).spawn(3)
    train_rng = np.random.default_rng(seeds[0])
    others = {}
    for label in params.get("others", ["least-squares"]):
        kind, options = parse_spec(label)
        others[label] = train_classifier(
            scenario,
            classifier.sequence_,
            int(params.get("n_train", 20)),
            train_rng,
            kind=kind,
            **options,
        )
    with_inertia = bool(params.get("inertia", True))
    share = 0.8 if with_inertia else 1.0
    sweep = run_sweep(
        classifier,
        others=others,
        limit_realisations=int(params.get("limit_realisations", 200)),
        seed=int(seeds[1].generate_state(1)[0]),
        progress=lambda fraction: context.report(progress=share * fraction),
        should_stop=context.should_stop,
        **_present(params, {"multiples": "multiples", "noises": "noises", "n_test": "n_test"}),
    )
    result = sweep.model_dump(mode="json")
    if with_inertia and not context.cancelled:
        inertia = run_inertia_sweep(
            classifier,
            seed=int(seeds[2].generate_state(1)[0]),
            progress=lambda fraction: context.report(progress=share + (1 - share) * fraction),
            should_stop=context.should_stop,
        )
        result["inertia"] = inertia.model_dump(mode="json")
    metrics = [
        (f"accuracy_{noise}", step, point.accuracy)
        for noise in dict.fromkeys(p.noise for p in sweep.points)
        for step, point in enumerate(sweep.curve(noise))
    ]
    status = "cancelled" if context.cancelled else "succeeded"
    return Outcome(status=status, result=result, metrics=metrics)


HANDLERS: dict[str, Callable[[JobContext], Outcome]] = {
    "search": run_search_job,
    "train": run_train_job,
    "sweep": run_sweep_job,
}
