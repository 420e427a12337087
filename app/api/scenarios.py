"""Scenarios: the spacecraft, its candidate configurations, thrusters, timing and noise."""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Depends, HTTPException, Query, Request, Response, status
from fastapi.exceptions import RequestValidationError
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError

from inertia_id.checks import DuplicateKeyError, control_characters, loads_unique_keys
from inertia_id.errors import InputError
from inertia_id.physics.presets import PRESETS, preset
from inertia_id.physics.scenario import Scenario, idle_thruster_warning
from inertia_id.physics.simulable import NoiseOverflow, check_simulable
from inertia_id.physics.simulate import (
    SimulationOverflow,
    check_gyro_range,
    check_nominal_gyro_range,
    settled_rates,
    simulate,
    weak_response_warning,
)
from service.exports import iso_utc, note_lines, plan_notes
from service.store.models import ClassifierRow, JobRow, ScenarioRow, utcnow
from service.store.session import Database

from ..capacity import ComputeGate
from ..plan_schema import PlanOut
from ..schemas import (
    MAX_SEED,
    CandidateOut,
    CandidateResponse,
    PlanRequest,
    ScenarioCreate,
    ScenarioOut,
    ScenarioPage,
    ScenarioResponse,
)
from .deps import (
    UNAUTHORIZED,
    ApiKeyDep,
    PagingDep,
    SessionDep,
    get_or_404,
    no_such,
    unprocessable,
)
from .errors import duplicate_key_errors, refused_at
from .idempotency import IDEMPOTENCY_RESPONSES, IdempotencyDep, replayable
from .listing import one_page
from .routing import UniqueKeysRoute

__all__ = ["PlanOptions", "PlanOptionsDep", "overflow_loc", "plan_for", "router", "scenario_out"]

router = APIRouter(prefix="/scenarios", tags=["scenarios"], route_class=UniqueKeysRoute)

_NOT_FOUND = no_such("scenario")

#: What the schema says of the 414 that a route taking a sequence in its query string
#: answers to a long one: the server refuses the head before the app sees it
#: (:mod:`app.request_deadlines`), so FastAPI cannot document it by itself.
_URL_TOO_LONG: dict[int | str, dict[str, Any]] = {
    414: {
        "description": "the request target (URL) is over INERTIA_ID_REQUEST_HEADER_MAX_BYTES "
        "(16,384 bytes by default: some 540 steps of six thrusters, as compact JSON, "
        "URL-encoded), refused before the route sees it and the connection closed; "
        "POST /scenarios/{id}/plan takes a longer sequence in its body"
    }
}

#: A sequence in the query string: its steps as JSON.
_SequenceQuery = Annotated[
    str,
    Query(
        max_length=20_000,
        description="JSON list of steps, each a level index per thruster: [[4,4,4,0,0,0]]",
    ),
]


def scenario_out(row: ScenarioRow) -> ScenarioOut:
    """The stored document plus what the dashboard plots: names and principal moments."""
    document = row.document
    candidates = [
        CandidateOut(
            name=c["name"],
            inertia_kg_m2=c["inertia_kg_m2"],
            principal_moments_kg_m2=np.linalg.eigvalsh(
                np.asarray(c["inertia_kg_m2"], dtype=float)
            ).tolist(),
        )
        for c in document.get("inertia_candidates", [])
    ]
    thrusters = document.get("thrusters", {})
    torque = thrusters.get("torque_matrix_nm") or [[]]
    idle = idle_thruster_warning(torque) if torque[0] else None
    return ScenarioOut(
        id=row.id,
        name=row.name,
        created_at=row.created_at,
        n_thrusters=len(torque[0]),
        n_levels=len(thrusters.get("levels", [])),
        candidates=candidates,
        document=document,
        warnings=[] if idle is None else [idle],
    )


def _build(body: ScenarioCreate) -> Scenario:
    if body.scenario is not None:
        return body.scenario
    assert body.preset is not None  # checked by the model
    # Located in the request: the overrides are Scenario fields.
    with refused_at(("body", "overrides")):
        return preset(body.preset, **body.overrides)


def _check_names(scenario: Scenario, source: str) -> None:
    """Refuse a name holding a control character (a newline, a tab, ...): names are
    written a line at a time into the CSV files a flight team uploads and reads."""
    names = [(("name",), scenario.name)] + [
        (("inertia_candidates", k, "name"), name) for k, name in enumerate(scenario.candidate_names)
    ]
    for where, name in names:
        found = control_characters(name)
        if found:
            unprocessable(
                ("body", source, *where),
                f"name {name!r} holds control characters ({', '.join(found)}); a name is "
                "one line of printable text",
            )


def _check_storable(scenario: Scenario) -> dict[str, Any]:
    document = scenario.model_dump(mode="json")
    text = json.dumps(document)  # ASCII: non-ASCII text appears as \u escapes
    # Neither database stores NUL in text, and a lone surrogate is not UTF-8.
    if "\\u0000" in text:
        unprocessable(("body",), "scenario text (names) must not contain NUL characters")
    try:
        json.dumps(document, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError as exc:
        unprocessable(("body",), f"scenario text (names) is not valid UTF-8: {exc.reason}")
    return document


def overflow_loc(exc: NoiseOverflow, past_1x: tuple[str, ...]) -> tuple[str, ...]:
    """Where a request whose simulations overflow is refused: when the scenario's own
    noise (1x) overflows, at its noise figure, located in the scenario document
    (``("uncertainty", field)``; the section when no figure overflows alone), as a
    stored scenario's other refusals are: a job, a plan's flights and a response all
    name it there; else at ``past_1x``, the parameter that asked for the multiple."""
    if exc.multiple != 1.0:
        return past_1x
    return ("uncertainty", exc.fields[0]) if len(exc.fields) == 1 else ("uncertainty",)


def _check_simulable(scenario: Scenario, source: str) -> None:
    """Refuse a scenario that cannot be simulated at its own noise
    (:func:`~inertia_id.physics.simulable.check_scenario_simulable`): every job on it
    would fail. Located at the noise figure when one alone overflows the rates."""
    from inertia_id.physics.simulable import check_scenario_simulable

    try:
        check_scenario_simulable(scenario)
    except NoiseOverflow as exc:
        unprocessable(("body", source, *overflow_loc(exc, ())), str(exc))
    except SimulationOverflow as exc:
        unprocessable(("body", source), str(exc))


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=ScenarioOut,
    dependencies=[ApiKeyDep],
    responses=replayable({**UNAUTHORIZED, **IDEMPOTENCY_RESPONSES}, status.HTTP_201_CREATED),
)
def create_scenario(body: ScenarioCreate, session: SessionDep, idempotent: IdempotencyDep) -> Any:
    """Store a scenario from a preset with overrides, or from a full document.

    Every rule of the physics is checked, e.g. an inertia tensor whose principal moments
    break the triangle inequality is refused (422) with the moments. What is allowed but
    likely a mistake is stored with a word in ``warnings``: a thruster that gives no
    torque (a zero column of the torque matrix). With an
    ``Idempotency-Key`` the same request sent again is answered as the first time, and
    stores no second scenario (:mod:`app.api.idempotency`).
    """
    if idempotent is not None and (replay := idempotent.begin(body)) is not None:
        return replay
    scenario = _build(body)
    document = _check_storable(scenario)
    source = "scenario" if body.scenario is not None else "overrides"
    _check_names(scenario, source)
    _check_simulable(scenario, source)
    row = ScenarioRow(name=scenario.name, document=document)
    session.add(row)
    session.flush()
    created = scenario_out(row)
    if idempotent is not None:
        # In the scenario's own transaction: both are kept, or neither.
        idempotent.answer(session, status.HTTP_201_CREATED, created)
    return created


@router.get("")
def list_scenarios(session: SessionDep, page: PagingDep) -> ScenarioPage:
    """Scenarios, newest first."""
    rows, total = one_page(
        session,
        select(ScenarioRow).order_by(ScenarioRow.created_at.desc(), ScenarioRow.id),
        count=select(func.count()).select_from(ScenarioRow),
        page=page,
    )
    return ScenarioPage(
        items=[scenario_out(r) for (r,) in rows], total=total, limit=page.limit, offset=page.offset
    )


@router.get("/presets")
def list_presets() -> dict[str, dict[str, Any]]:
    """The built-in scenarios as documents, by name: a starting point for a new scenario."""
    return {name: make().model_dump(mode="json") for name, make in sorted(PRESETS.items())}


@router.get("/{scenario_id}", responses=_NOT_FOUND)
def get_scenario(scenario_id: str, session: SessionDep) -> ScenarioOut:
    return scenario_out(get_or_404(session, ScenarioRow, scenario_id, "scenario"))


@router.get("/{scenario_id}/baselines", responses=_NOT_FOUND)
def scenario_baselines(
    scenario_id: str,
    session: SessionDep,
    length: int = Query(default=4, ge=1, le=64, description="steps"),
) -> dict[str, list[list[int]] | dict[str, str]]:
    """The baseline sequences of ``length`` steps for this scenario's thrusters, as the
    core defines them (level indices, one row per step): what searches are compared with,
    and what the dashboard proposes to train on. Every baseline is named; one that the
    length or the thrusters do not allow (fire then brake needs 2 steps, fire, coast,
    brake 3) is ``{"unavailable": why}``, as in a search result, not a refusal of the
    whole list."""
    from inertia_id.physics.sequences import baseline_sequences

    row = get_or_404(session, ScenarioRow, scenario_id, "scenario")
    scenario = Scenario.model_validate(row.document)
    return {
        name: {"unavailable": sequence} if isinstance(sequence, str) else sequence.tolist()
        for name, sequence in baseline_sequences(scenario, length).items()
    }


@router.delete(
    "/{scenario_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    dependencies=[ApiKeyDep],
    responses={
        **_NOT_FOUND,
        **UNAUTHORIZED,
        409: {"description": "jobs or classifiers use the scenario"},
    },
)
def delete_scenario(scenario_id: str, session: SessionDep) -> Response:
    """Delete a scenario that no job or classifier uses (409 otherwise)."""
    row = get_or_404(session, ScenarioRow, scenario_id, "scenario")
    # On PostgreSQL, wait for submissions holding the row (FOR SHARE) to commit, so the
    # counts below see their jobs; SQLite serialises writers and the foreign key decides.
    session.execute(select(ScenarioRow.id).where(ScenarioRow.id == row.id).with_for_update())
    jobs = session.scalar(select(func.count()).where(JobRow.scenario_id == row.id)) or 0
    classifiers = (
        session.scalar(select(func.count()).where(ClassifierRow.scenario_id == row.id)) or 0
    )
    if jobs or classifiers:
        raise HTTPException(
            status.HTTP_409_CONFLICT,
            detail=f"scenario {row.id!r} is used by {jobs} job(s) and {classifiers} "
            "classifier(s); it cannot be deleted",
        )
    session.delete(row)
    try:
        session.flush()
    except IntegrityError:
        # A job was submitted for it between the count and the delete.
        session.rollback()
        raise HTTPException(
            status.HTTP_409_CONFLICT, detail=f"scenario {row.id!r} is in use by a new job"
        ) from None
    return Response(status_code=status.HTTP_204_NO_CONTENT)


#: Work cap of one response simulation: 400,000 candidate-realisation-RK4-steps (the cap
#: was 13.7 s of CPU before; the integrator, compiled since, flies them in 0.05 s).
MAX_RESPONSE_WORK = 400_000
#: Rate values (samples x 3) a response's series may hold, as a job's series
#: (``app.api.jobs.MAX_SERIES_VALUES`` is this): with the RK4 steps a job may fly
#: (:data:`MAX_PLAN_INTEGRATION_STEPS`), every sequence a search may find is drawn. The
#: response took 1,280 RK4 steps, and a search page could not draw its 16-step best
#: sequence on a 10 ms RK4 step (1,600).
MAX_RESPONSE_SERIES_VALUES = 8_192
#: RK4 steps a plan's nominal prediction may take (one run of the candidates, no
#: realisations): as many as a job may fly a flight (``app.api.jobs.MAX_FLIGHT_RK4_STEPS``
#: is this), so that every sequence a search or training was accepted for can be planned.
#: At the response's 1,280 a 20-step search on a 10 ms RK4 step (a 20 ms thruster lag)
#: found sequences whose plan was a 422. 100,000 (1,000 steps on a 10 ms step, 5
#: candidates) took 2.1 s in command_plan and 3.5 to 4.8 s a request with its 875 kB of
#: JSON (the 2-core machine at a load average of 2); 20 such steps 0.11 s.
MAX_PLAN_INTEGRATION_STEPS = 100_000
#: Flights a plan may fly (``flights=``): candidates x flights x RK4 steps at most this,
#: about 0.5 s of CPU on the 2-core machine (measured: 1,250 flights of 8 paper steps
#: 0.50 s; 156 of 64 steps 0.25 s).
MAX_PLAN_FLIGHT_WORK = 1_000_000


def _parse_sequence(text: str, scenario: Scenario) -> np.ndarray:
    try:
        rows = loads_unique_keys(text)
    except DuplicateKeyError as exc:
        raise RequestValidationError(duplicate_key_errors(exc, ("query", "sequence"))) from None
    except (ValueError, RecursionError):  # not JSON, digits beyond the limit, deep nesting
        unprocessable(
            ("query", "sequence"),
            f"sequence must be a JSON list of rows of level indices like "
            f"[[4,4,4,0,0,0]], got {text[:120]!r}",
        )
    if not isinstance(rows, list) or not all(
        isinstance(row, list) and all(isinstance(v, int) and not isinstance(v, bool) for v in row)
        for row in rows
    ):
        unprocessable(
            ("query", "sequence"),
            f"sequence must be a JSON list of rows of integer level indices, got {text[:120]!r}",
        )
    try:
        return scenario.check_sequence(rows)
    except InputError as exc:
        unprocessable(("query", "sequence"), str(exc))


@router.get(
    "/{scenario_id}/response",
    dependencies=[ApiKeyDep],
    responses={
        **_NOT_FOUND,
        **UNAUTHORIZED,
        **_URL_TOO_LONG,
        503: {"description": "past capacity: try again after Retry-After seconds"},
    },
)
async def scenario_response(
    scenario_id: str,
    request: Request,
    sequence: _SequenceQuery,
    n_realisations: int = Query(default=20, ge=2, le=200),
    seed: int = Query(default=0, ge=0, le=MAX_SEED),
) -> ScenarioResponse:
    """Simulate every candidate's measured rate response to a sequence.

    Per candidate: the mean over ``n_realisations`` noisy realisations and the 10th and
    90th percentiles (the band the dashboard draws), the final true rate, and the
    sequence's commanded impulse. Same seed, same answer. It costs CPU, so it needs the
    API key, is capped in size, and runs behind the compute gate (503 past capacity).
    """
    gate: ComputeGate = request.app.state.compute_gate
    return await gate.run(
        _response, request.app.state.db, scenario_id, sequence, n_realisations, seed
    )


def _response(
    database: Database, scenario_id: str, sequence: str, n_realisations: int, seed: int
) -> ScenarioResponse:
    with database.session() as session:
        row = get_or_404(session, ScenarioRow, scenario_id, "scenario")
        scenario_id, document = row.id, row.document
    scenario = Scenario.model_validate(document)
    steps = _parse_sequence(sequence, scenario)
    timing = scenario.timing
    integration = len(steps) * round(timing.step_duration_s / timing.integration_step_s)
    work = scenario.n_candidates * n_realisations * integration
    values = len(steps) * timing.samples_per_step * 3
    if integration > MAX_PLAN_INTEGRATION_STEPS:
        unprocessable(
            ("query", "sequence"),
            f"{len(steps)} steps of {timing.step_duration_s:g} s at an integration step of "
            f"{timing.integration_step_s:g} s = {integration} RK4 steps; at most "
            f"{MAX_PLAN_INTEGRATION_STEPS}",
        )
    if values > MAX_RESPONSE_SERIES_VALUES:
        unprocessable(
            ("query", "sequence"),
            f"{len(steps)} steps of {timing.step_duration_s:g} s at {timing.sample_rate_hz:g} "
            f"Hz = {values} rate values; at most {MAX_RESPONSE_SERIES_VALUES}",
        )
    if work > MAX_RESPONSE_WORK:
        unprocessable(
            ("query", "n_realisations"),
            f"{scenario.n_candidates} candidates x {n_realisations} realisations x "
            f"{integration} RK4 steps = {work}; at most {MAX_RESPONSE_WORK}: ask for fewer "
            "realisations",
        )
    try:
        # The plan's rule (search.plan.command_plan) on the same quantity: the nominal
        # true rate at every integration step and once the lag has emptied, so the two
        # refuse a sequence alike (this route checked only its gyro samples: 94 rad/s
        # answered where the plan refused 105 once the lag emptied).
        nominal = check_nominal_gyro_range(scenario, steps)
    except SimulationOverflow as exc:
        unprocessable(("query", "sequence"), str(exc))
    # The plan's and the training's warning on the same prediction: the search page's
    # best-sequence charts and the classifier page draw this response.
    weak = weak_response_warning(scenario, steps, nominal)
    try:
        # Told by the figure that overflows (a scenario stored before scenarios were
        # checked for it), rather than after the realisations are flown.
        check_simulable(scenario, steps, sequence_name="the sequence")
        result = simulate(scenario, steps, n_realisations, np.random.default_rng(seed))
        # And the realisations shown, with their lag's tails, as a plan checks its flights.
        check_gyro_range(
            scenario,
            steps,
            result.omega_true,
            settled=settled_rates(
                scenario, result.omega_true[:, :, -1], result.applied_torque_nm[:, :, -1]
            ),
            flight=lambda i: f"realisation {i + 1} of {n_realisations} (seed {seed})",
        )
    except NoiseOverflow as exc:
        unprocessable(overflow_loc(exc, ("query", "n_realisations")), str(exc))
    except SimulationOverflow as exc:
        unprocessable(("query", "n_realisations"), str(exc))
    omega = result.omega_measured  # (K, n, T, 3)
    low, high = np.percentile(omega, [10.0, 90.0], axis=1)
    mean = omega.mean(axis=1)
    final = result.final_rate_rad_s.mean(axis=1)
    return ScenarioResponse(
        scenario_id=scenario_id,
        sequence=steps.tolist(),
        duties=scenario.duties(steps).tolist(),
        step_duration_s=scenario.timing.step_duration_s,
        time_s=scenario.sample_times(len(steps)).tolist(),
        n_realisations=n_realisations,
        seed=seed,
        impulse_nms=scenario.impulse_nms(steps),
        candidates=[
            CandidateResponse(
                name=name,
                mean_rad_s=mean[k].tolist(),
                low_rad_s=low[k].tolist(),
                high_rad_s=high[k].tolist(),
                final_rate_rad_s=float(final[k]),
            )
            for k, name in enumerate(scenario.candidate_names)
        ],
        warnings=[] if weak is None else [weak],
    )


@dataclass(frozen=True)
class PlanOptions:
    """What every plan route takes beside the sequence: the file's format and the single
    flights to fly (0: the nominal prediction alone) from ``seed``."""

    format: str
    flights: int
    seed: int


def plan_options(
    format: Annotated[str, Query(pattern="^(json|csv)$", description="json or csv")] = "json",
    flights: Annotated[
        int,
        Query(
            ge=0,
            le=100_000,
            description="fly the sequence this many times a candidate at the scenario's "
            "noise (0: none; at least 2) and state how the residual and peak rates spread "
            "over single flights: mean, 95th percentile, a 95 %-confidence bound, largest",
        ),
    ] = 0,
    seed: Annotated[int, Query(ge=0, le=MAX_SEED, description="seed of the flights")] = 0,
) -> PlanOptions:
    return PlanOptions(format, flights, seed)


PlanOptionsDep = Annotated[PlanOptions, Depends(plan_options)]


def _nominal_fits(scenario: Scenario, steps: np.ndarray) -> bool:
    """Whether the plan's nominal prediction of ``steps`` stays finite and in any gyro's
    range (no flights)."""
    try:
        check_nominal_gyro_range(scenario, steps)
    except SimulationOverflow:
        return False
    return True


def _plan_response(
    scenario: Scenario,
    steps: np.ndarray,
    options: PlanOptions,
    source: dict[str, Any],
    where: tuple[str, ...] = ("query", "sequence"),
    job: Mapping[str, Any] | None = None,
) -> Response:
    """The plan, with where it comes from (``source``: the scenario's id, and the search
    job and front member when it is one) in the JSON, in the CSV's ``#`` lines and in the
    file's name, so that plans downloaded side by side can be told apart and traced; the
    CSV's lines say when it was exported and, for a plan of a ``job``'s sequence, which
    job it is as every CSV of the job does (:func:`service.exports.plan_notes`)."""
    from inertia_id.search.plan import command_plan

    timing = scenario.timing
    integration = len(steps) * round(timing.step_duration_s / timing.integration_step_s)
    if integration > MAX_PLAN_INTEGRATION_STEPS:
        per_step = round(timing.step_duration_s / timing.integration_step_s)
        unprocessable(
            where,
            f"{len(steps)} steps: at most {MAX_PLAN_INTEGRATION_STEPS // per_step} steps "
            f"on this scenario ({per_step} RK4 steps each, at most "
            f"{MAX_PLAN_INTEGRATION_STEPS} in all)",
        )
    fmt, flights = options.format, options.flights
    work = scenario.n_candidates * flights * integration
    if work > MAX_PLAN_FLIGHT_WORK:
        unprocessable(
            ("query", "flights"),
            f"{scenario.n_candidates} candidates x {flights} flights x {integration} RK4 "
            f"steps = {work}; at most {MAX_PLAN_FLIGHT_WORK}: ask for fewer flights",
        )
    try:
        plan = command_plan(scenario, steps, flights=flights, seed=options.seed)
    except NoiseOverflow as exc:
        # The scenario's own noise, which the flights fly (a row stored before
        # scenarios were checked for it): named at its figure, as a job names it.
        unprocessable(overflow_loc(exc, ("query", "flights")), str(exc))
    except SimulationOverflow as exc:
        # The nominal prediction overflowing is the sequence's (on this scenario), not
        # the flights' (it was named at query.flights with no flights asked for); the
        # flights' own draws only when the nominal plan alone goes through.
        unprocessable(
            ("query", "flights") if flights and _nominal_fits(scenario, steps) else where, str(exc)
        )
    except InputError as exc:
        unprocessable(("query", "flights"), str(exc))
    stem = "plan-" + "-".join(
        f"{key.removesuffix('_id')}-{str(source[key])[:8]}"
        for key in ("scenario_id", "job_id", "member")
        if key in source
    )
    if source.get("job_status") == "cancelled":
        stem += "-cancelled"  # the best sequence a cancelled search had found
    exported_at = utcnow()
    if fmt == "csv":
        lines = note_lines(plan_notes(source, job, exported_at))
        return Response(
            lines + plan.to_csv(),
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="{stem}.csv"'},
        )
    return Response(
        # When it was written (UTC, as the CSV's `# exported_at` line says it): a plan
        # handed on to be uploaded says how fresh it is.
        json.dumps({"source": source, "exported_at": iso_utc(exported_at), **plan.to_dict()}),
        media_type="application/json",
        headers={"Content-Disposition": f'attachment; filename="{stem}.json"'},
    )


def plan_for(
    database: Database,
    scenario_id: str,
    sequence: Any,
    options: PlanOptions,
    *,
    parsed: bool = False,
    source: dict[str, Any] | None = None,
    where: tuple[str, ...] = ("query", "member"),
    job: Mapping[str, Any] | None = None,
) -> Response:
    """The command plan of a sequence for a stored scenario (JSON or CSV); ``source``
    names the search job and member it comes from, beside the scenario's id, and ``job``
    is that job (:func:`service.exports.job_notes`), for the CSV's lines. A ``parsed``
    sequence (a list of rows) that the scenario refuses is named at ``where``."""
    with database.session() as session:
        row = get_or_404(session, ScenarioRow, scenario_id, "scenario")
        document = row.document
    scenario = Scenario.model_validate(document)
    if parsed:
        try:
            steps = scenario.check_sequence(sequence)
        except InputError as exc:
            unprocessable(where, str(exc))
    else:
        steps = _parse_sequence(sequence, scenario)
    return _plan_response(
        scenario,
        steps,
        options,
        {"scenario_id": scenario_id, **(source or {})},
        where if parsed else ("query", "sequence"),
        job,
    )


_PLAN_RESPONSES: dict[int | str, dict[str, Any]] = {
    **_NOT_FOUND,
    **UNAUTHORIZED,
    200: {
        "description": "the plan as JSON (steps with on-times and torque, candidates with "
        "predicted rates in rad/s and deg/s, residual rates, attitude change, propellant) "
        "or as CSV (one row per step, totals as '#' lines)",
        "model": PlanOut,
        "content": {"application/json": {}, "text/csv": {}},
    },
    503: {"description": "past capacity: try again after Retry-After seconds"},
}


@router.get(
    "/{scenario_id}/plan",
    dependencies=[ApiKeyDep],
    responses={**_PLAN_RESPONSES, **_URL_TOO_LONG},
    response_class=Response,
)
async def scenario_plan(
    scenario_id: str,
    request: Request,
    sequence: _SequenceQuery,
    options: PlanOptionsDep,
) -> Response:
    """The command plan of a sequence: per step and thruster the PWM on-time (s) and
    duty, the commanded torque (N m), each candidate's predicted rates (rad/s, deg/s) at
    every step's end with every noise off, its residual rate and attitude change
    (quaternion and angle), and the propellant figures (on-time, commanded impulse
    summed over thrusters, propellant mass when the scenario gives thrust and Isp).
    With ``flights``, how single flights spread around that nominal prediction."""
    gate: ComputeGate = request.app.state.compute_gate
    return await gate.run(plan_for, request.app.state.db, scenario_id, sequence, options)


@router.post(
    "/{scenario_id}/plan",
    dependencies=[ApiKeyDep],
    responses=_PLAN_RESPONSES,
    response_class=Response,
)
async def scenario_plan_from_body(
    scenario_id: str,
    request: Request,
    body: PlanRequest,
    options: PlanOptionsDep,
) -> Response:
    """The command plan of the sequence in the body (``{"sequence": [[4,4,4,0,0,0], ...]}``):
    the same plan as ``GET /scenarios/{id}/plan?sequence=``, for a sequence too long for
    a URL. A plan takes at most 100,000 RK4 steps, as many as a job may fly (a sequence's
    1,000 steps on the paper preset's 0.05 s integration step, 100 on a 1 ms one); 1,000
    steps are 30 kB URL-encoded, past what a proxy keeping its default request-line limit
    passes (nginx: 8 kB, some 280 steps), and the query takes at most 20,000 characters."""
    gate: ComputeGate = request.app.state.compute_gate
    planned = functools.partial(plan_for, parsed=True, where=("body", "sequence"))
    return await gate.run(planned, request.app.state.db, scenario_id, body.sequence, options)
