"""What each job type does: typed params -> a pipeline of the core -> an :class:`Outcome`.

Pure: a handler reads its typed parameters and resolved inputs from the context, calls
the pipeline and returns what it got; it never reads or writes the store (the runner
resolves and persists, :mod:`worker.runner`). Imported only inside the task process: it
pulls in numba and the core. A job's params become the pipeline's request
(:mod:`inertia_id.pipelines`), whose defaults are the core's, and the pipeline runs with
the job's seed: the command line calls the same pipelines with the same seeding, so a
job and the CLI give the same numbers.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Callable
from typing import Any

from inertia_id.pipelines import (
    SearchRequest,
    SweepRequest,
    TrainRequest,
    search_with_baselines,
    sweep_with_limit,
    train_for_sequence,
)
from inertia_id.search import SearchProgress
from inertia_id.stopping import TrainingStopped
from service.exports import FEASIBLE_METRIC, SEARCH_METRICS, TRAIN_METRICS

from .context import TIME_LIMIT, JobContext, JobTimeLimitExceeded, Outcome

__all__ = ["HANDLERS", "run_search_job", "run_sweep_job", "run_train_job"]


def _params(context: JobContext) -> dict[str, Any]:
    return context.spec.params.model_dump(mode="json")


def run_search_job(context: JobContext) -> Outcome:
    """Search for the actuation sequence, then score the baselines on its fresh draws.

    Metrics: :data:`SEARCH_METRICS` at step = timesteps, after every curve point, and
    :data:`FEASIBLE_METRIC` too where the search has constraints.
    A PPO policy is saved to ``data_dir/policies/<job id>.zip`` and its path and
    SHA-256 put in the result. The search runs to the job's time limit (its own, at most
    the service's ceiling) on the context's clock: past it, it stops with its best so
    far re-scored, ``stopped`` "time_limit", and the job succeeds.
    """
    spec = context.spec
    request = dataclasses.replace(
        SearchRequest.from_params(_params(context)), time_limit_s=context.time_limit_s
    )
    policy_path = None
    if request.method == "ppo":
        policy = context.data_dir / "policies" / f"{spec.id}.zip"
        policy.parent.mkdir(parents=True, exist_ok=True)
        policy_path = str(policy)

    def progress(report: SearchProgress) -> None:
        point = report.point
        # Between curve points (NSGA-II's front measurement) only the progress moves:
        # the curve the dashboard draws is the stored result's, one point per
        # generation and per polish round.
        metrics = [(key, report.timesteps, getattr(point, key)) for key in SEARCH_METRICS]
        if request.constraints:
            metrics.append((FEASIBLE_METRIC, report.timesteps, float(point.best_feasible)))
        context.report(progress=report.fraction, metrics=metrics if report.new_point else [])

    outcome = search_with_baselines(
        spec.scenario,
        request,
        seed=spec.seed,
        policy_path=policy_path,
        progress=progress,
        should_stop=context.should_stop,
        clock=context.now,
    )
    result = outcome.to_dict()
    if outcome.result.policy_path is not None:
        with open(outcome.result.policy_path, "rb") as fh:
            result["policy_sha256"] = hashlib.sha256(fh.read()).hexdigest()
    status = "cancelled" if outcome.result.stopped == "cancelled" else "succeeded"
    return Outcome(status=status, result=result)


class _StopOrTimeLimit:
    """A job's ``should_stop`` for a library call that stops between its pieces: True
    once the job is cancelled or its run taken from it (:meth:`JobContext.should_stop`,
    which reads the cancel flag at most every CANCEL_POLL_S) or its time limit has
    passed (a clock read, cheap at every call); :attr:`timed_out` says it was the limit."""

    def __init__(self, context: JobContext) -> None:
        self.context = context
        self.timed_out = False

    def __call__(self) -> bool:
        if self.context.should_stop():
            return True
        self.timed_out = self.context.past_time_limit()
        return self.timed_out


def run_train_job(context: JobContext) -> Outcome:
    """Train the classifier for a sequence; the runner stores it as a ``classifiers`` row.

    The training draws (and a seed the kind needs) come from the job's seed. Metrics:
    "f1" and "accuracy" at step 0. The training stops part-way, at its next checkpoint
    (:func:`~inertia_id.pipelines.train_for_sequence`), once a cancel is asked for, the
    run is taken from it (its worker stopping hands the job back: the runner drops the
    run) or the job's time limit has passed; nothing half-trained is stored. A cancel
    ends it "cancelled"; the time limit fails it, naming the limit.
    """
    spec = context.spec
    stop = _StopOrTimeLimit(context)
    try:
        trained = train_for_sequence(
            spec.scenario,
            TrainRequest.from_params(_params(context)),
            seed=spec.seed,
            should_stop=stop,
        )
    except TrainingStopped:
        if context.cancelled or context.lost or not stop.timed_out:
            # A lost run's outcome is dropped by the runner, as a stopped search's is.
            return Outcome(status="cancelled", result=None)
        raise JobTimeLimitExceeded(context.time_limit_text()) from None
    if context.check_now():
        return Outcome(status="cancelled", result=None)
    if context.past_time_limit():
        raise JobTimeLimitExceeded(context.time_limit_text())
    summary = trained.summary()
    return Outcome(
        status="succeeded",
        result=summary,
        metrics=[(key, 0, summary[key]) for key in TRAIN_METRICS],
        classifier=trained,
    )


def run_sweep_job(context: JobContext) -> Outcome:
    """Accuracy of a stored classifier as each source of error grows, on the job's
    scenario (one with other candidates than the classifier's is refused).

    ``others`` (default: least squares) are trained at 1x on the classifier's sequence
    and scored on the same test series, and so is the limit (a likelihood classifier
    fitted at each point's noise, ``limit_realisations`` per candidate); with
    ``inertia`` the result also says how often bodies off the candidates are flagged
    "matches none". Metrics: "accuracy_<noise>" for each noise swept, one point per
    multiple, at step = the multiple's index in the job's ``multiples`` list (0, 1, ...),
    value = the accuracy there. A cancel stops between points; the points done are kept.
    So does the job's time limit: the job then succeeds with the points done, and the
    result says ``"stopped": "time_limit"``; a limit that ran out before the first point
    fails the job naming it, as a training's does (it had "succeeded" with no point).
    """
    spec = context.spec
    if spec.classifier is None:
        raise ValueError("a sweep job runs with the classifier it names, resolved by the runner")
    stop = _StopOrTimeLimit(context)
    outcome = sweep_with_limit(
        spec.classifier,
        SweepRequest.from_params(_params(context)),
        seed=spec.seed,
        scenario=spec.scenario,
        progress=lambda fraction: context.report(progress=fraction),
        should_stop=stop,
    )
    sweep = outcome.sweep
    metrics = [
        (f"accuracy_{noise}", step, point.accuracy)
        for noise in dict.fromkeys(p.noise for p in sweep.points)
        for step, point in enumerate(sweep.curve(noise))
    ]
    status = "cancelled" if context.cancelled else "succeeded"
    if stop.timed_out and status == "succeeded" and not sweep.points:
        raise JobTimeLimitExceeded(f"{context.time_limit_text()} before the first sweep point")
    result = outcome.to_dict()
    if stop.timed_out and status == "succeeded":
        result["stopped"] = TIME_LIMIT
        result["time_limit_s"] = context.time_limit_s
    return Outcome(status=status, result=result, metrics=metrics)


HANDLERS: dict[str, Callable[[JobContext], Outcome]] = {
    "search": run_search_job,
    "train": run_train_job,
    "sweep": run_sweep_job,
}
