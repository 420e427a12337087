"""Jobs: submit (search, train, sweep), list, inspect, follow metrics, cancel.

The ``jobs`` table is the source of truth; the broker only delivers the job id to a
worker (by task name, :data:`service.queue.RUN_JOB_TASK`). A job with the same type,
scenario, parameters and seed as one that is queued, running or succeeded is not run
twice: that job is returned (200, ``reused``) unless ``rerun`` is asked for and that
job has finished (a plain rerun of a queued or running job is handed it, so a burst of
reruns makes one job), or it is asked to stop (it ends with no result: a new job takes
its place); a unique key in the database makes this hold for submissions
that race each other too. A rerun that names the job it replaces (``rerun_of``) makes a
new job only while that job still stands, so the same rerun sent twice makes one job.
"""

from __future__ import annotations

import functools
import json
import logging
from typing import Annotated, Any, Literal

import numpy as np
from fastapi import APIRouter, Body, Depends, HTTPException, Query, Request, Response, status
from sqlalchemy import ColumnElement, func, or_, select
from sqlalchemy.orm import defer

from inertia_id.errors import InputError
from inertia_id.physics.scenario import Scenario
from inertia_id.physics.simulable import NoiseOverflow, check_simulable
from inertia_id.physics.simulate import check_nominal_gyro_range
from service.exports import (
    RESULT_TABLES,
    job_notes,
    job_status_notes,
    metric_keys,
    metrics_notes,
    metrics_table,
    metrics_with_degrees,
    result_table,
    to_csv,
    to_records,
)
from service.queue import RUN_JOB_TASK
from service.store import jobs as job_store
from service.store.models import (
    TERMINAL_STATUSES,
    ClassifierRow,
    JobRow,
    MetricRow,
    ScenarioRow,
    utcnow,
)
from service.summaries import summary_keys

from ..plan_schema import PlanOut
from ..schemas import (
    JobCreate,
    JobListed,
    JobListInclude,
    JobOut,
    JobPage,
    JobStatus,
    JobStopped,
    JobSubmitted,
    JobType,
    JobUpdate,
    MetricSeries,
    MetricsOut,
    SearchJobCreate,
    SweepJobCreate,
    TrainJobCreate,
)
from .deps import (
    UNAUTHORIZED,
    ApiKeyDep,
    CeleryDep,
    OrderQuery,
    PagingDep,
    SessionDep,
    SettingsDep,
    TagText,
    get_or_404,
    job_tagged,
    no_such,
    plausible_id,
    quoted,
    quoted_id,
    sort_query,
    text_query,
    unknown_sort,
    unprocessable,
)
from .idempotency import IDEMPOTENCY_RESPONSES, IdempotencyDep, replayable
from .listing import id_filters, one_page, search_text, sort_order, tag_filters
from .routing import UniqueKeysRoute
from .scenarios import (
    MAX_PLAN_INTEGRATION_STEPS,
    MAX_RESPONSE_SERIES_VALUES,
    PlanOptionsDep,
    overflow_loc,
    plan_for,
)

__all__ = ["router"]

log = logging.getLogger(__name__)

router = APIRouter(prefix="/jobs", tags=["jobs"], route_class=UniqueKeysRoute)

_NOT_FOUND = no_such("job")


def _scenario(session: SessionDep, scenario_id: str) -> Scenario:
    row = get_or_404(session, ScenarioRow, scenario_id, "scenario")
    # Held until the job is committed: a concurrent delete of the scenario (FOR UPDATE on
    # PostgreSQL) waits, then sees the job and refuses.
    session.execute(
        select(ScenarioRow.id).where(ScenarioRow.id == row.id).with_for_update(read=True)
    )
    return Scenario.model_validate(row.document)


def _check_search(body: SearchJobCreate, scenario: Scenario) -> None:
    params = body.params
    _check_size(
        scenario,
        params.sequence_length,
        params.n_realisations,
        ("body", "params", "sequence_length"),
    )
    # What needs the scenario (a propellant objective or bound needs thrust and specific
    # impulse): refused here, not after the job has waited in the queue.
    from inertia_id.pipelines import SearchRequest
    from inertia_id.search.objectives import check_rate_floor

    try:
        operator = SearchRequest.from_params(params.model_dump(mode="json")).operator()
        checked = operator.check(scenario, params.sequence_length)
        check_rate_floor(dict(checked.constraints), scenario, params.sequence_length)
    except InputError as exc:
        message = str(exc)
        field = (
            "design_noise"
            if message.startswith("design_noise")
            else "objectives"
            if "objective" in message
            else "constraints"
        )
        unprocessable(("body", "params", field), message)
    from inertia_id.pipelines import check_search_scenario

    try:
        check_search_scenario(
            scenario, params.sequence_length, params.constraints, checked.design_noise
        )
    except NoiseOverflow as exc:
        unprocessable(overflow_loc(exc, ("body", "params", "design_noise")), str(exc))
    except InputError as exc:
        unprocessable(("body", "scenario_id"), str(exc))
    if params.method != "exhaustive":
        return
    from inertia_id.search import space_size

    size = space_size(scenario, params.sequence_length)
    if size > params.max_sequences:
        m, n, length = scenario.n_levels, scenario.n_thrusters, params.sequence_length
        unprocessable(
            ("body", "params", "max_sequences"),
            f"the space holds ({m}^{n})^{length} = {_approx(size)} sequences, more than the "
            f"budget max_sequences = {params.max_sequences} for exhaustive search; shorten "
            "the sequence, raise the budget, or use method random or ppo",
        )


def _approx(count: int) -> str:
    """``count`` in 4 significant digits; beyond float range (101^1280), as a power of 10."""
    try:
        return f"{count:.4g}"
    except OverflowError:
        return f"about 10^{len(str(count)) - 1}"


def _resolve_front_member(session: SessionDep, body: TrainJobCreate, scenario: Scenario) -> None:
    """Fill in a train job's sequence from the search job (and front member) it names."""
    params = body.params
    if params.search_job_id is None:
        return
    where = ("body", "params", "search_job_id")
    search = get_or_404(session, JobRow, params.search_job_id, "job")
    if search.type != "search" or search.status != "succeeded" or not search.result:
        # A search stopped after it had found a sequence has it planned (GET
        # /jobs/{id}/plan): say how to train on it rather than only refuse.
        found = (
            (search.result or {}).get("best", {}).get("sequence")
            if search.type == "search"
            else None
        )
        unprocessable(
            where,
            f"job {search.id!r} is a {search.type} job, {search.status}: name a succeeded "
            "search job"
            + (
                f", or give the best sequence it had found as params.sequence: {found}"
                if found
                else ""
            ),
        )
    result = search.result
    _same_spacecraft(search, body.scenario_id, scenario)
    if params.front_member is None:
        sequence = (result.get("best") or {}).get("sequence")
    else:
        members = (result.get("front") or {}).get("members") or []
        found = [m for m in members if m.get("index") == params.front_member]
        if not found:
            unprocessable(
                ("body", "params", "front_member"),
                f"search job {search.id!r} has no front member {params.front_member} "
                f"(it holds {len(members)})",
            )
        sequence = found[0]["sequence"]
        try:
            scenario.check_fires(sequence)
        except InputError as exc:
            unprocessable(
                ("body", "params", "front_member"),
                f"front member {params.front_member} of search job {search.id!r} cannot be "
                f"trained on: {exc}. The front keeps it as its least-impulse end (marked "
                '"fires": false); pick another member',
            )
    if params.sequence is not None and params.sequence != sequence:
        unprocessable(
            ("body", "params", "sequence"),
            f"sequence {params.sequence} is not the one search job {search.id!r} names "
            f"({sequence}); give one or the other",
        )
    params.sequence = sequence


def _same_spacecraft(search: JobRow, scenario_id: str, scenario: Scenario) -> None:
    """A sequence found on one scenario is level indices of that scenario's thrusters: on
    another (other levels, thrusters or candidates) the same indices fly something else.
    So a training on a search's sequence runs on the search's scenario, or on one that
    differs from it in name only (:meth:`Scenario.same_spacecraft`: its levels to their
    last bits of rounding too)."""
    if search.scenario_id == scenario_id:
        return
    searched = (search.result or {}).get("scenario")
    if isinstance(searched, dict):
        try:
            ran_on = Scenario.model_validate(searched)
        except ValueError:  # a result stored by older code: judged by its id alone
            ran_on = None
        if ran_on is not None and ran_on.same_spacecraft(scenario):
            return
    unprocessable(
        ("body", "scenario_id"),
        f"search job {search.id!r} ran on scenario {search.scenario_id!r}, not "
        f"{scenario_id!r}, which is not the same spacecraft (level indices mean duties of "
        "one scenario's thrusters); train on the search's scenario, or give the sequence "
        "itself",
    )


#: What one job may ask the worker to hold and integrate. Without these a valid-looking
#: request (a scenario with hour-long steps, a long sequence, many realisations) was
#: accepted and the worker grew past every limit until the kernel killed it, with nothing
#: to say why; and a classifier document of hundreds of MB was stored for every read to
#: load. The paper preset at its largest (64 steps, 400 realisations, the 8,000-flight
#: ceiling) fits each with room to spare.
#: (The most a plan takes too: every sequence a job flies can be planned.)
MAX_FLIGHT_RK4_STEPS = MAX_PLAN_INTEGRATION_STEPS
MAX_SERIES_VALUES = MAX_RESPONSE_SERIES_VALUES  # (a response draws any such series)
MAX_HELD_VALUES = 2**23
MAX_COVARIANCE_VALUES = 2**27


def _check_size(
    scenario: Scenario, n_steps: int, per_candidate: int, where: tuple[str, ...]
) -> None:
    """422 (at ``where``) for a job whose flights or series exceed what a worker holds:
    ``per_candidate`` flights of ``n_steps`` steps per candidate at once."""
    timing, k = scenario.timing, scenario.n_candidates
    rk4 = n_steps * timing.substeps_per_step
    d = n_steps * timing.samples_per_step * 3
    shape = (
        f"{n_steps} steps of {timing.step_duration_s:g} s (RK4 step "
        f"{timing.integration_step_s:g} s, gyro at {timing.sample_rate_hz:g} Hz)"
    )
    problem = None
    if rk4 > MAX_FLIGHT_RK4_STEPS:
        problem = f"{shape} are {rk4} RK4 steps a flight; at most {MAX_FLIGHT_RK4_STEPS:,}"
    elif d > MAX_SERIES_VALUES:
        problem = f"{shape} are {d} rate values a series; at most {MAX_SERIES_VALUES:,}"
    elif k * per_candidate * d > MAX_HELD_VALUES:
        problem = (
            f"{k} candidates x {per_candidate} flights x {d} values a series = "
            f"{k * per_candidate * d:,} values; at most {MAX_HELD_VALUES:,}: ask for fewer "
            "realisations or a shorter sequence"
        )
    elif k * d * d > MAX_COVARIANCE_VALUES:
        problem = (
            f"{k} candidates' covariances of {d} x {d} values (a series of {shape}) = "
            f"{k * d * d:,} values; at most {MAX_COVARIANCE_VALUES:,}: shorten the sequence"
        )
    if problem is not None:
        unprocessable(where, f"the job is too large for a worker: {problem}")


def _check_train(body: TrainJobCreate, scenario: Scenario) -> None:
    from inertia_id.classifiers.registry import (
        DEFAULT_KIND,
        check_document_size,
        default_realisations,
    )

    where = ("body", "params")
    try:
        scenario.check_distinguishable()
    except InputError as exc:
        # The worker refused it, once the job had waited in the queue.
        unprocessable(("body", "scenario_id"), str(exc))
    try:
        rows = scenario.check_fires(body.params.sequence)
    except InputError as exc:
        unprocessable((*where, "sequence"), str(exc))
    # Calibration flies 200 fresh series a candidate beside the training ones.
    realisations = max(body.params.n_realisations or 0, 200)
    _check_size(scenario, len(rows), realisations, (*where, "n_realisations"))
    # The classifier it makes must be one the CLI loads (MAX_CLASSIFIER_BYTES): a 2-candidate
    # scenario's 8,192-value series made a 1.9 GB document that identify --classifier refused.
    kind = body.params.kind or DEFAULT_KIND
    trained = body.params.n_realisations or default_realisations(kind)
    try:
        check_document_size(kind, scenario, len(rows), trained)
    except InputError as exc:
        unprocessable((*where, "sequence"), f"the job's classifier is too large: {exc}")
    try:
        check_nominal_gyro_range(scenario, rows)
    except InputError as exc:
        unprocessable((*where, "sequence"), str(exc))
    try:
        check_simulable(scenario, rows, sequence_name="the training's sequence")
    except NoiseOverflow as exc:
        # The scenario's own noise overflows the rates (a row stored before scenarios
        # were checked for it, or one that overflows on this sequence's length only).
        unprocessable(overflow_loc(exc, ("body", "scenario_id")), str(exc))
    except InputError as exc:
        unprocessable(("body", "scenario_id"), str(exc))


def _check_sweep(session: SessionDep, body: SweepJobCreate, scenario: Scenario) -> None:
    params = body.params
    classifier = get_or_404(session, ClassifierRow, params.classifier_id, "classifier")
    if list(classifier.candidate_names) != scenario.candidate_names:
        unprocessable(
            ("body", "params", "classifier_id"),
            f"classifier {classifier.id!r} was trained for candidates "
            f"{classifier.candidate_names}, but the scenario has {scenario.candidate_names}",
        )
    try:
        scenario.check_sequence(classifier.sequence)
    except InputError as exc:
        unprocessable(
            ("body", "params", "classifier_id"),
            f"the classifier's sequence does not fit the scenario: {exc}",
        )
    if params.n_test < scenario.n_candidates:
        unprocessable(
            ("body", "params", "n_test"),
            f"n_test = {params.n_test} is fewer than the {scenario.n_candidates} candidates",
        )
    # The ceiling flies its realisations in batches (its covariances are counted).
    held = max(params.n_train, -(-params.n_test // scenario.n_candidates))
    _check_size(scenario, len(classifier.sequence), held, ("body", "params", "n_train"))
    try:
        check_nominal_gyro_range(scenario, classifier.sequence)
    except InputError as exc:
        unprocessable(("body", "params", "classifier_id"), str(exc))
    from inertia_id.evaluation.sweep import check_sweep_simulable

    try:
        check_sweep_simulable(scenario, classifier.sequence, params.noises, params.multiples)
    except NoiseOverflow as exc:
        unprocessable(overflow_loc(exc, ("body", "params", "multiples")), str(exc))


def _check_time_limit(body: JobCreate, ceiling_s: float) -> None:
    """A job may ask for less run time than the service's ceiling, never more."""
    asked = getattr(body.params, "time_limit_s", None)
    if asked is not None and asked > ceiling_s:
        unprocessable(
            ("body", "params", "time_limit_s"),
            f"time_limit_s = {asked:g} s is more than this service's ceiling of "
            f"{ceiling_s:g} s (INERTIA_ID_JOB_TIME_LIMIT_S); ask for at most that, or leave "
            "it out to get the ceiling",
        )


#: Parameters a job type gained after jobs of that type were stored, left out of the
#: stored parameters (and so of the configuration hash) while not asked for: a train job
#: stored before its ``time_limit_s`` has the same identity as one submitted since
#: without it (an identical submission reuses it; ``rerun_of`` may name it). Searches
#: hold theirs as null: their hashes have since ea351e4, and changing it now would
#: part every search stored since from its identical submissions.
_LATER_PARAMS: dict[str, tuple[str, ...]] = {"train": ("time_limit_s",)}


def _stored_params(body: JobCreate) -> dict[str, Any]:
    """The job's parameters as stored and hashed (:data:`_LATER_PARAMS`)."""
    params: dict[str, Any] = body.params.model_dump(mode="json")
    for name in _LATER_PARAMS.get(body.type, ()):
        if params.get(name) is None:
            params.pop(name, None)
    return params


def _check_rerun_of(
    session: SessionDep, body: JobCreate, params: dict[str, Any], rerun_of: str
) -> None:
    """``rerun_of`` names a job of this submission's configuration, and asks for a rerun."""
    where = ("body", "rerun_of")
    if "rerun" in body.model_fields_set and not body.rerun:
        unprocessable(
            where,
            f"rerun_of = {rerun_of!r} asks for a rerun, but rerun is false; leave "
            "rerun out or set it true",
        )
    # An id no job can have (a NUL byte, which PostgreSQL refuses in text) is looked up in
    # no table, as on every route.
    replaced = session.get(JobRow, rerun_of) if plausible_id(rerun_of) else None
    if replaced is None:
        unprocessable(where, f"no job {rerun_of!r} to rerun")
    digest = job_store.config_hash(body.type, body.scenario_id, params, body.seed)
    if replaced.config_hash != digest:
        unprocessable(
            where,
            f"job {rerun_of!r} is not this submission's job: its type, scenario, "
            "params or seed differ (a rerun replaces a job of the same configuration)",
        )


async def _note_asked_at(request: Request) -> None:
    # On the event loop, before the key check and the submission's checks: the moment
    # the request was taken up. Ten reruns sent at once are taken up within milliseconds,
    # then checked one after another (tens of ms each, under load), so this, not the
    # handler's start, tells which job was made since a rerun was asked (create_job).
    request.state.asked_at = utcnow()


@router.post(
    "",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=JobSubmitted,
    dependencies=[Depends(_note_asked_at), ApiKeyDep],
    responses=replayable(
        {
            200: {
                "model": JobSubmitted,
                "description": "an identical job exists (for a rerun: one that already "
                "replaced the job it asked to replace, or, for a plain rerun, one still "
                "queued or running and not asked to stop); it is returned, "
                "`reused_note` saying why and how to run it anew",
            },
            **no_such("scenario or classifier"),
            **UNAUTHORIZED,
            **IDEMPOTENCY_RESPONSES,
        },
        status.HTTP_200_OK,
        status.HTTP_202_ACCEPTED,
    ),
)
def submit_job(
    body: Annotated[JobCreate, Body()],
    session: SessionDep,
    celery: CeleryDep,
    settings: SettingsDep,
    request: Request,
    response: Response,
    idempotent: IdempotencyDep,
) -> Any:
    """Queue a search, train or sweep job (202), or return the identical existing one (200).

    The job is stored before its message goes to the broker. If the broker cannot be
    reached the job stays queued (``sent_at`` null) and the workers' monitor sends it
    once the broker is back; ``GET /health`` says how many jobs wait to be sent.

    With an ``Idempotency-Key`` the same request sent again is answered as the first
    time (:mod:`app.api.idempotency`).
    """
    if idempotent is not None and (replay := idempotent.begin(body)) is not None:
        return replay
    _check_time_limit(body, settings.job_time_limit_s)
    scenario = _scenario(session, body.scenario_id)
    if isinstance(body, SearchJobCreate):
        _check_search(body, scenario)
    elif isinstance(body, TrainJobCreate):
        _resolve_front_member(session, body, scenario)
        _check_train(body, scenario)
    else:
        _check_sweep(session, body, scenario)
    params = _stored_params(body)
    if body.rerun_of is not None:
        _check_rerun_of(session, body, params, body.rerun_of)

    def answer_made(job: JobRow) -> None:
        # The job is committed before the send below: the key's answer is committed with
        # it, so a request that fails or dies after that (the send, the commit of the
        # answer below) is answered with its job when retried, and makes no second one.
        assert idempotent is not None
        made = JobSubmitted.model_validate({**_as_dict(job), "reused": False})
        idempotent.answer(session, status.HTTP_202_ACCEPTED, made)

    try:
        job, reused = job_store.create_job(
            session,
            job_type=body.type,
            scenario_id=body.scenario_id,
            params=params,
            seed=body.seed,
            rerun=body.rerun,
            rerun_of=body.rerun_of,
            name=body.name,
            tags=body.tags or (),
            asked_at=request.state.asked_at,
            on_insert=answer_made if idempotent is not None else None,
        )
    except job_store.ScenarioGone:
        raise HTTPException(
            status.HTTP_404_NOT_FOUND,
            detail=f"scenario {body.scenario_id!r} was deleted while the job was submitted",
        ) from None
    if reused:
        response.status_code = status.HTTP_200_OK
        submitted = JobSubmitted.model_validate(
            {**_as_dict(job), "reused": True, "reused_note": _reused_note(body, job)}
        )
        if idempotent is not None:
            idempotent.answer(session, status.HTTP_200_OK, submitted)
        return submitted
    try:
        celery.send_task(RUN_JOB_TASK, args=[job.id])
    except Exception:  # any broker failure: the job waits, queued, for the monitor's send
        log.warning("could not send job %s to the broker; it stays queued", job.id, exc_info=True)
    else:
        job_store.mark_sent(session, job.id)
        session.commit()
        session.refresh(job)
    submitted = JobSubmitted.model_validate({**_as_dict(job), "reused": False})
    if idempotent is not None:
        idempotent.answer(session, status.HTTP_202_ACCEPTED, submitted)
    return submitted


def _reused_note(body: JobCreate, job: JobRow) -> str:
    """Why ``job`` answers the submission ``body`` instead of a new run, and how to get
    one: a client that sent ``"rerun": true`` and got 200 with the old job back had only
    ``reused`` to go by, and a job stuck running on a dead worker looked like a rerun
    refused for no reason. Then the labels of ``body`` that ``job`` lacks, if any."""
    return _why_reused(body, job) + _labels_not_applied(body, job)


def _labels_not_applied(body: JobCreate, job: JobRow) -> str:
    """What of the submission's ``name`` and ``tags`` the job handed back lacks, and the
    ``PATCH`` that sets it; empty when it lacks none.

    A submission handed a job that stands does not relabel it: that job is someone's
    (another submission's, another user's), and a resubmission with other labels must
    not rename it by surprise. But the labels were dropped without a word, and a rerun
    sent to tag a new run found its tags nowhere.
    """
    name = body.name if body.name is not None and body.name != job.name else None
    have = job.tags
    missing = [tag for tag in dict.fromkeys(body.tags or ()) if tag not in have]
    if name is None and not missing:
        return ""
    dropped: list[str] = []
    change: dict[str, Any] = {}
    if name is not None:
        named = f"named {job.name!r}" if job.name is not None else "unnamed"
        dropped.append(f"name {name!r} (it is {named})")
        change["name"] = name
    if missing:
        tagged = f"tagged {have}" if have else "untagged"
        what = f"tag {missing[0]!r}" if len(missing) == 1 else f"tags {missing}"
        dropped.append(f"{what} (it is {tagged})")
        change["tags"] = [*have, *missing]
    # One label "was" not applied, several "were" (it said "name 'A again' ... were").
    verb, them = ("was", "it") if (name is not None) + len(missing) == 1 else ("were", "them")
    return (
        f"; this submission's {' and '.join(dropped)} {verb} not applied to it, labels of "
        f"a job that stands being changed only on purpose: to set {them}, PATCH "
        f"/jobs/{job.id} with {json.dumps(change)}"
    )


def _why_reused(body: JobCreate, job: JobRow) -> str:
    cancel = f"POST /jobs/{job.id}/cancel"
    if body.rerun_of is not None:
        return (
            f"job {body.rerun_of} was already replaced by this identical job (a rerun of it "
            "sent earlier or at the same time): it is returned, not run once more"
        )
    unfinished = job.status in job_store.UNFINISHED_STATUSES and not job.cancel_requested
    if body.rerun and unfinished:
        return (
            f"not rerun: the identical job {job.id} is still {job.status} (same scenario, "
            "parameters and seed: same result), so a rerun is handed it; to run it anew, "
            f'cancel it ({cancel}) and send the rerun again, or send "rerun_of": "{job.id}"'
        )
    if body.rerun:
        return (
            f"an identical rerun sent at the same time made job {job.id}: it is returned, "
            "not run once more"
        )
    if unfinished:
        return (
            f"the identical job {job.id} is {job.status}: it is returned, not run twice; to "
            f'run it anew, cancel it ({cancel}) and resubmit with "rerun": true, or send '
            f'"rerun_of": "{job.id}"'
        )
    return (
        f"the identical job {job.id} is {job.status}: it is returned, not run again; send "
        '"rerun": true to run it anew'
    )


def _as_dict(job: JobRow) -> dict[str, Any]:
    return {name: getattr(job, name) for name in JobOut.model_fields}


#: What a job list sorts by: the row's own columns, and every summary figure.
_SORT_COLUMNS: dict[str, Any] = {
    "created": JobRow.created_at,
    "started": JobRow.started_at,
    "finished": JobRow.finished_at,
    "name": func.lower(JobRow.name),
    "status": JobRow.status,
    "type": JobRow.type,
    "seed": JobRow.seed,
    "progress": JobRow.progress,
}
JOB_SORT_KEYS = (*_SORT_COLUMNS, *summary_keys())


def _sort_expression(sort: str) -> Any:
    if sort in _SORT_COLUMNS:
        return _SORT_COLUMNS[sort]
    if sort in summary_keys():
        return JobRow.summary[sort].as_float()
    unknown_sort("jobs", sort, JOB_SORT_KEYS)


def _text_match(needle: str) -> ColumnElement[bool]:
    """Name contains ``needle`` (lower case; any case in the name), the id starts with it,
    or a tag contains it."""
    return or_(
        func.lower(JobRow.name).contains(needle, autoescape=True),
        JobRow.id.startswith(needle, autoescape=True),
        job_tagged(JobRow.id, containing=needle),
    )


#: The columns a listed job is built from (its result stays in the database unless asked).
_LISTED_FIELDS = tuple(name for name in JobListed.model_fields if name != "result")


def _listed(job: JobRow, *, with_result: bool) -> JobListed:
    """``job`` as the list shows it. Without its result the field is left unset, and
    the route leaves unset fields out: no ``result`` key, where null would read as
    "no result yet"."""
    fields = {name: getattr(job, name) for name in _LISTED_FIELDS}
    if with_result:
        fields["result"] = job.result
    return JobListed.model_validate(fields)


# The list sends what a list shows (labels, state, times, parameters, the summary's
# headline figures), not each job's result: a search's result (curve, front, baselines,
# fresh draws) is tens of KB, and a page of 200 was megabytes for a table that shows two
# figures a row. As GitHub's lists send a resource's summary representation and its GET
# the detailed one, GET /jobs/{id} keeps the whole job; a client that does want results
# for a few jobs (the sweeps of one classifier) asks with ``include=result``, opt-in as
# Stripe's ``expand`` and Google's AIP-157 list views (BASIC by default, FULL on request).
# ``include`` rather than a ``view`` enum: it names what is added, and can name more.
@router.get("", response_model_exclude_unset=True)
def list_jobs(
    session: SessionDep,
    page: PagingDep,
    include: Annotated[
        JobListInclude | None,
        Query(
            description="result: each job's whole result too (as GET /jobs/{id}); "
            "without it a listed job has no result key, its summary holds the headline "
            "figures"
        ),
    ] = None,
    type: Annotated[JobType | None, Query(description="search, train or sweep")] = None,
    status: Annotated[JobStatus | None, Query()] = None,
    stopped: Annotated[
        JobStopped | None,
        Query(
            description="time_limit: jobs their time limit stopped (failed naming it, or "
            "succeeded with what they had; GET /vocabulary stopped_reasons)"
        ),
    ] = None,
    scenario_id: Annotated[str | None, Query(max_length=64)] = None,
    q: Annotated[
        str | None, text_query("text in the name (any case), an id prefix, or text in a tag")
    ] = None,
    tag: Annotated[
        list[TagText] | None,
        Query(description="jobs carrying this tag (repeat for all of several)"),
    ] = None,
    classifier_id: Annotated[
        str | None, Query(max_length=64, description="sweeps of this classifier")
    ] = None,
    sort: Annotated[
        str,
        sort_query(
            JOB_SORT_KEYS,
            "created, started, finished, name, status, type, seed, progress, or a "
            "summary figure (GET /vocabulary job_summaries), e.g. fresh_f1",
        ),
    ] = "created",
    order: OrderQuery = "desc",
) -> JobPage:
    """Jobs, filtered by type, status, what stopped them, scenario, text, tags and
    classifier, sorted (newest first by default; jobs without the figure sorted by come
    last), one page at a time.

    Each job comes without its result (its ``summary`` has the headline figures) unless
    ``include=result`` asks for it; ``GET /jobs/{id}`` always has it."""
    # A sweep names its classifier in its parameters.
    conditions = id_filters(
        (
            (JobRow.scenario_id, scenario_id),
            (JobRow.params["classifier_id"].as_string(), classifier_id),
        )
    )
    if conditions is None:
        return JobPage(items=[], total=0, limit=page.limit, offset=page.offset)
    if classifier_id is not None:
        conditions.append(JobRow.type == "sweep")
    if type is not None:
        conditions.append(JobRow.type == type)
    if status is not None:
        conditions.append(JobRow.status == status)
    if stopped is not None:
        conditions.append(JobRow.stopped == stopped)
    needle = search_text(q)
    if needle is not None:
        conditions.append(_text_match(needle))
    conditions.extend(tag_filters(JobRow.id, tag))
    with_result = include == "result"
    # Not read at all without include: a page of results is most of the list's time. A
    # read of it by mistake raises, rather than costing a query a row.
    query = select(JobRow)
    if not with_result:
        query = query.options(defer(JobRow.result, raiseload=True))
    rows, total = one_page(
        session,
        query.where(*conditions).order_by(
            sort_order(_sort_expression(sort), order), JobRow.created_at.desc(), JobRow.id
        ),
        count=select(func.count()).select_from(JobRow).where(*conditions),
        page=page,
    )
    return JobPage(
        items=[_listed(job, with_result=with_result) for (job,) in rows],
        total=total,
        limit=page.limit,
        offset=page.offset,
    )


@router.patch(
    "/{job_id}",
    dependencies=[ApiKeyDep],
    responses={**_NOT_FOUND, **UNAUTHORIZED},
)
def update_job(job_id: str, body: JobUpdate, session: SessionDep) -> JobOut:
    """Rename or retag a job. Labels only: its parameters, seed, identity and result stay."""
    job = get_or_404(session, JobRow, job_id, "job")
    job_store.set_labels(
        session,
        job,
        name=body.name,
        tags=body.tags if "tags" in body.model_fields_set else None,
        rename="name" in body.model_fields_set,
    )
    session.flush()
    session.refresh(job)
    return JobOut.model_validate(job)


ExportFormat = Literal["json", "csv"]
_TABLE_NAMES = list(dict.fromkeys(name for tables in RESULT_TABLES.values() for name in tables))


def _download(content: str, media_type: str, filename: str) -> Response:
    return Response(
        content=content,
        media_type=media_type,
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )


@router.get(
    "/{job_id}/result",
    response_class=Response,
    responses={
        200: {
            "content": {
                "application/json": {
                    "schema": {
                        "anyOf": [
                            {"type": "object"},
                            {"type": "array", "items": {"type": "object"}},
                        ]
                    }
                },
                "text/csv": {"schema": {"type": "string"}},
            },
            "description": "the result as a file (Content-Disposition: attachment): the "
            "job with its whole result, or a named table's rows",
        },
        **_NOT_FOUND,
        409: {"description": "the job has no result (yet)"},
    },
)
def download_result(
    job_id: str,
    session: SessionDep,
    format: Annotated[ExportFormat, Query(description="json or csv")] = "json",
    table: Annotated[
        str | None,
        Query(
            max_length=64,
            description="which table of the job type's (GET /vocabulary result_tables): "
            "with csv, default the first; with json, that table's rows as objects instead "
            "of the whole result",
            json_schema_extra={"enum": _TABLE_NAMES},
        ),
    ] = None,
) -> Response:
    """A job's result as a file: JSON (the job's labels and parameters with the whole
    result) or one of its tables as CSV, or as JSON (one object per row) when ``table`` is
    named with ``format=json`` (a search's summary, curve, sequence, baselines and front;
    a training's summary, confusion matrix and sequence; a sweep's points, confusion
    matrices and bodies off the candidates)."""
    job = get_or_404(session, JobRow, job_id, "job")
    if job.result is None:
        # "yet" only where one may come: a failed or cancelled job will never have one.
        why = (
            f"it {'failed' if job.status == 'failed' else 'was ' + job.status} before it "
            "made one; there is nothing to download"
            if job.status in TERMINAL_STATUSES
            else f"it is {job.status}; nothing to download yet"
        )
        raise HTTPException(status.HTTP_409_CONFLICT, detail=f"job {job.id} has no result: {why}")
    out = JobOut.model_validate(job)
    stem = f"{job.type}-{job.id[:8]}"
    if format == "json" and table is None:
        document = out.model_dump(mode="json", exclude={"config_hash"})
        return _download(
            json.dumps(document, indent=1, allow_nan=False), "application/json", f"{stem}.json"
        )
    try:
        rendered = result_table(job.type, out.result or {}, table, _job_facts(job))
    except InputError as exc:
        unprocessable(("query", "table"), str(exc))
    name = table or next(iter(RESULT_TABLES.get(job.type, {})), "table")  # the default's
    if format == "json":
        records = json.dumps(to_records(rendered), indent=1, allow_nan=False)
        return _download(records, "application/json", f"{stem}-{name}.json")
    return _download(to_csv(rendered), "text/csv; charset=utf-8", f"{stem}-{name}.csv")


def _job_facts(job: JobRow) -> dict[str, Any]:
    """What a job's CSV exports say about it (:func:`service.exports.job_notes`)."""
    return {
        "id": job.id,
        "type": job.type,
        "scenario_id": job.scenario_id,
        "seed": job.seed,
        "created_at": job.created_at,
        "finished_at": job.finished_at,
        "status": job.status,
        "params": job.params or {},
    }


@router.get("/{job_id}", responses=_NOT_FOUND)
def get_job(job_id: str, session: SessionDep) -> JobOut:
    """Status, progress (0 to 1), timestamps, error text and result summary."""
    return JobOut.model_validate(get_or_404(session, JobRow, job_id, "job"))


@router.get(
    "/{job_id}/metrics",
    response_model=MetricsOut,
    responses={
        200: {
            "content": {"text/csv": {"schema": {"type": "string"}}},
            "description": "the series (JSON), or with format=csv every point as key,step,value",
        },
        404: {
            "description": "no such job; or no such series: a `key` the job never records "
            "(none of its type's, or one its parameters leave out), or one a finished job "
            "did not record; the detail names the key and lists the job's series. A queued "
            "or running job's `key` that it records but has not yet is a 200 with no series"
        },
    },
)
def get_metrics(
    job_id: str,
    session: SessionDep,
    settings: SettingsDep,
    key: Annotated[
        str | None,
        Query(
            max_length=64,
            pattern=r"^[^\x00]*$",
            description="one series only: one the job's type records (404 otherwise, and for "
            "a finished job that did not record it)",
        ),
    ] = None,
    after: Annotated[
        int | None,
        Query(ge=-(2**31), le=2**31 - 1, description="only points with step > after"),
    ] = None,
    format: Annotated[
        ExportFormat, Query(description="json (series, downsampled) or csv (every point)")
    ] = "json",
) -> Any:
    """Metric series of a job (reward curve, F1...), incremental with ``after``.

    A series longer than the server's cap (INERTIA_ID_MAX_METRIC_POINTS) is thinned to
    evenly spaced points, first and last kept; ``last_step`` is always the true last step.
    ``format=csv`` downloads every point, never thinned. A series in rad/s
    (``best_residual_rate_rad_s``) is followed by its deg/s twin, made from it
    (``best_residual_rate_deg_s``).
    """
    job = get_or_404(session, JobRow, job_id, "job")
    recorded = _recorded_keys(session, job)
    if key is not None and key not in recorded:
        _refuse_unrecorded(job, key, recorded)
    query = select(MetricRow.key, MetricRow.step, MetricRow.value).where(MetricRow.job_id == job.id)
    if key is not None:
        # A deg/s series is made from its rad/s twin (metrics_with_degrees).
        query = query.where(MetricRow.key.in_({key, key.replace("_deg_s", "_rad_s")}))
    if after is not None:
        query = query.where(MetricRow.step > after)
    stored = session.execute(query.order_by(MetricRow.key, MetricRow.step, MetricRow.id)).all()
    rows = [
        point
        for point in metrics_with_degrees([(k, s, v) for k, s, v in stored])
        if key is None or point[0] == key
    ]
    if format == "csv":
        points = [(k, s, v if np.isfinite(v) else None) for k, s, v in rows]
        return _download(
            to_csv(
                metrics_table(
                    points,
                    [
                        *job_notes(_job_facts(job), utcnow()),
                        *job_status_notes(_job_facts(job)),
                        *metrics_notes(job.type, job.params or {}),
                    ],
                )
            ),
            "text/csv; charset=utf-8",
            f"{job.type}-{job.id[:8]}-metrics.csv",
        )
    by_key: dict[str, tuple[list[int], list[float]]] = {}
    for name, step, value in rows:
        steps, values = by_key.setdefault(name, ([], []))
        steps.append(step)
        values.append(value)
    return MetricsOut(
        job_id=job.id,
        series=[
            _series(name, steps, values, settings.max_metric_points)
            for name, (steps, values) in by_key.items()
        ],
        keys=recorded,
    )


def _recorded_keys(session: SessionDep, job: JobRow) -> list[str]:
    """The series ``job`` has recorded so far, each rad/s one with its deg/s twin, in the
    order the series are listed (:func:`service.exports.metrics_with_degrees`)."""
    stored = session.scalars(
        select(MetricRow.key).where(MetricRow.job_id == job.id).distinct()
    ).all()
    return [
        key for key, _step, _value in metrics_with_degrees([(k, 0, 0.0) for k in sorted(stored)])
    ]


def _refuse_unrecorded(job: JobRow, key: str, recorded: list[str]) -> None:
    """404 for a ``?key=`` that ``job`` has not recorded, where it never will: one its
    type (and parameters) does not record, or any, once the job has finished. A queued or
    running job's key that it records later passes (its answer lists no series)."""
    known = metric_keys(job.type, job.params or {})
    has = f"it has {', '.join(recorded)}" if recorded else "it has recorded none"
    if known is not None and key not in known:
        raise HTTPException(
            status.HTTP_404_NOT_FOUND,
            detail=f"job {quoted_id(job.id)} ({job.type}) never records a series "
            f"{quoted(key)}: its series are {', '.join(known)}; {has}",
        )
    if job.status in TERMINAL_STATUSES:
        raise HTTPException(
            status.HTTP_404_NOT_FOUND,
            detail=f"job {quoted_id(job.id)} has no series {quoted(key)} (it {job.status} "
            f"without recording it); {has}",
        )


def _series(key: str, steps: list[int], values: list[float], cap: int) -> MetricSeries:
    total = len(steps)
    last_step = steps[-1] if steps else None
    downsampled = total > cap
    if downsampled:
        keep = np.unique(np.round(np.linspace(0, total - 1, max(cap, 2))).astype(int))
        steps = [steps[i] for i in keep]
        values = [values[i] for i in keep]
    return MetricSeries(
        key=key,
        steps=steps,
        values=[v if np.isfinite(v) else None for v in values],
        total_points=total,
        downsampled=downsampled,
        last_step=last_step,
    )


@router.post(
    "/{job_id}/cancel",
    dependencies=[ApiKeyDep],
    responses={
        **_NOT_FOUND,
        **UNAUTHORIZED,
        409: {"description": "the job already succeeded or failed"},
    },
)
def cancel_job(job_id: str, session: SessionDep) -> JobOut:
    """Cancel a job: a queued one now, a running one at its next check (cooperative)."""
    job = get_or_404(session, JobRow, job_id, "job")
    if job.status in TERMINAL_STATUSES and job.status != "cancelled":
        raise HTTPException(
            status.HTTP_409_CONFLICT, detail=f"job {job.id} already {job.status}; nothing to cancel"
        )
    job_store.cancel(session, job)
    session.flush()
    return JobOut.model_validate(job)


@router.get(
    "/{job_id}/plan",
    dependencies=[ApiKeyDep],
    responses={
        **_NOT_FOUND,
        **UNAUTHORIZED,
        200: {
            "description": "the plan as JSON (as GET /scenarios/{id}/plan, its source naming "
            "the job and member) or as CSV",
            "model": PlanOut,
            "content": {"application/json": {}, "text/csv": {}},
        },
        409: {"description": "the search has no sequence to plan (yet)"},
        422: {"description": "not a search job, or no such front member"},
        503: {"description": "past capacity: try again after Retry-After seconds"},
    },
    response_class=Response,
)
async def job_plan(
    job_id: str,
    request: Request,
    options: PlanOptionsDep,
    member: Annotated[
        int | None,
        Query(ge=0, le=10_000, description="front member index; default the best sequence"),
    ] = None,
) -> Response:
    """The command plan (as ``GET /scenarios/{id}/plan``) of a search job's best sequence
    or of one member of its front, for the job's scenario. A cancelled search that kept
    a partial result plans the best sequence it had found (the plan's source says
    ``job_status: cancelled``)."""

    database = request.app.state.db
    with database.session() as session:
        job = get_or_404(session, JobRow, job_id, "job")
        kind, state, result, scenario_id = job.type, job.status, job.result, job.scenario_id
        facts = _job_facts(job)
    if kind != "search":
        unprocessable(("path", "job_id"), f"job {job_id!r} is a {kind} job: no plan")
    best = ((result or {}).get("best") or {}).get("sequence")
    if state not in ("succeeded", "cancelled") or not result or (member is None and not best):
        # As GET /jobs/{id}/result: the search is the right kind, it has no result (yet).
        raise HTTPException(
            status.HTTP_409_CONFLICT,
            detail=f"search job {job_id} is {state}: it has no sequence to plan",
        )
    if member is None:
        sequence = best
    else:
        members = (result.get("front") or {}).get("members") or []
        found = [m for m in members if m.get("index") == member]
        if not found:
            unprocessable(
                ("query", "member"),
                f"search job {job_id!r} has no front member {member} (it holds {len(members)})",
            )
        sequence = found[0]["sequence"]
    gate = request.app.state.compute_gate
    # The gate passes positional arguments only.
    source = {"job_id": job_id, "member": "best" if member is None else member}
    if state == "cancelled":
        source["job_status"] = "cancelled"  # the best it had found when it stopped
    planned = functools.partial(plan_for, parsed=True, source=source, job=facts)
    return await gate.run(planned, database, scenario_id, sequence, options)
