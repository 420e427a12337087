"""The command plan's JSON (``GET/POST /scenarios/{id}/plan``, ``GET /jobs/{id}/plan``) as
response models, for the OpenAPI schema only.

The routes answer :meth:`inertia_id.search.plan.CommandPlan.to_dict` (with ``source``
first) as a plain :class:`~fastapi.Response`, unchanged: these models describe that
JSON, field by field. The published schema allows fields it does not list (a client
validating strictly against it still reads a later release's plan);
``tests/api/test_plan_schema.py`` validates real answers against its strict variant
(:func:`app.result_schema.strict_document`), so that a field added to the plan and not
here fails there.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["PlanOut"]


class _Out(BaseModel):
    model_config = ConfigDict(extra="allow")


class PlanSource(_Out):
    scenario_id: str = Field(description="the scenario the plan is flown on")
    job_id: str | None = Field(
        default=None, description="the search job the sequence comes from (GET /jobs/{id}/plan)"
    )
    member: int | Literal["best"] | None = Field(
        default=None, description="the front member's index, or best (the search's best)"
    )
    job_status: Literal["cancelled"] | None = Field(
        default=None, description="cancelled: the best sequence a cancelled search had found"
    )


class PlanStep(_Out):
    step: int = Field(description="numbered from 1")
    start_s: float
    end_s: float
    levels: list[int] = Field(description="each thruster's level index (N,)")
    duty: list[float] = Field(description="each thruster's commanded duty (N,)")
    on_time_s: list[float] = Field(description="each thruster's PWM on-time (N,), s")
    torque_nm: list[float] = Field(description="commanded body torque (3,), N m")


class PlanFlights(_Out):
    """One candidate's spread over single flights (with ``flights``)."""

    residual_rate_mean_rad_s: float
    residual_rate_p95_rad_s: float
    residual_rate_p95_bound_rad_s: float
    residual_rate_max_rad_s: float
    peak_rate_p95_rad_s: float
    peak_rate_p95_bound_rad_s: float
    residual_rate_mean_deg_s: float
    residual_rate_p95_deg_s: float
    residual_rate_p95_bound_deg_s: float
    residual_rate_max_deg_s: float
    peak_rate_p95_deg_s: float
    peak_rate_p95_bound_deg_s: float


class PlanCandidate(_Out):
    name: str
    number: int = Field(description="numbered from 1, as the CSV's candidate_<number> columns")
    rates_rad_s: list[list[float]] = Field(
        description="predicted body rates at each step's end (L, 3), every noise off"
    )
    rates_deg_s: list[list[float]]
    residual_rate_rad_s: float = Field(
        description="|ω| once the actuation lag has delivered its torque (from rest)"
    )
    residual_rate_deg_s: float
    commanded_residual_rate_rad_s: float = Field(
        description="the same: the part the commands leave (the prediction starts from rest)"
    )
    commanded_residual_rate_deg_s: float
    end_rate_rad_s: float = Field(description="|ω| when the last command ends")
    end_rate_deg_s: float
    peak_rate_rad_s: float
    peak_rate_deg_s: float
    attitude_quaternion: list[float] = Field(description="final attitude (w, x, y, z)")
    attitude_change_deg: float
    flights: PlanFlights | None = Field(
        default=None, description="present only when the plan flew the sequence (flights > 0)"
    )


class PlanFlightsSummary(_Out):
    flights_per_candidate: int
    seed: int
    percentile: float
    percentile_method: str
    p95_bound_note: str
    noise: str
    residual_rate_p95_max_rad_s: float
    residual_rate_p95_max_deg_s: float
    residual_rate_p95_bound_max_rad_s: float
    residual_rate_p95_bound_max_deg_s: float
    residual_rate_max_rad_s: float
    residual_rate_max_deg_s: float
    peak_rate_p95_max_rad_s: float
    peak_rate_p95_max_deg_s: float
    peak_rate_p95_bound_max_rad_s: float
    peak_rate_p95_bound_max_deg_s: float


class InitialRateFloor(_Out):
    initial_rate_sigma_rad_s: float
    mean_rad_s: float
    mean_deg_s: float
    p95_rad_s: float
    p95_deg_s: float


class PlanPropellant(_Out):
    on_time_per_thruster_s: list[float]
    on_time_s: float
    impulse_nms: float
    impulse_note: str
    propellant_kg: float | None = Field(
        description="null unless the scenario gives thrust and specific impulse"
    )
    propellant_note: str = Field(
        description="how propellant_kg is reached, or, when it is null, 'not stated' and "
        "the thruster fields the scenario lacks (the CSV's # propellant_kg line's words)"
    )


class PlanDust(_Out):
    """What the plan's figures were read against: one at most ``fraction`` of its scale
    is rounding dust (thrusters whose torques cancel) and is written 0."""

    fraction: float
    torque_scale_nm: float = Field(description="the largest thruster's torque, max |A_j|")
    rate_scale_rad_s: list[float] = Field(
        description="per candidate: the largest rate the sequence's firings could give it "
        "(the impulse summed over thrusters over its smallest principal moment)"
    )
    attitude_change_scale_deg: list[float] = Field(
        description="per candidate: that rate over the sequence's duration"
    )
    note: str


class PlanOut(_Out):
    """A command plan as JSON: the sequence as commands and the predicted response."""

    source: PlanSource
    exported_at: str = Field(description="when the plan was written: ISO 8601 in UTC, with Z")
    scenario: str = Field(description="the scenario's name")
    sequence: list[list[int]]
    step_duration_s: float
    duration_s: float
    steps: list[PlanStep]
    candidates: list[PlanCandidate]
    flights: PlanFlightsSummary | None = Field(description="null unless flights > 0")
    residual_rate_max_rad_s: float
    residual_rate_max_deg_s: float
    commanded_residual_rate_max_rad_s: float
    commanded_residual_rate_max_deg_s: float
    initial_rate_floor: InitialRateFloor | None = Field(
        description="what |ω(0)| alone leaves a flight; null for a scenario at rest"
    )
    peak_rate_max_rad_s: float
    peak_rate_max_deg_s: float
    attitude_quaternion_convention: str
    residual_rate_note: str
    propellant: PlanPropellant
    warnings: list[str]
    dust: PlanDust | None = Field(
        default=None,
        description="the scales dust was read against (a figure at most "
        "`fraction` of its scale is written 0); null in a plan made without them",
    )
