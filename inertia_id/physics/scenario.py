"""The spacecraft scenario: inertia candidates, thrusters, timing and uncertainty.

A :class:`Scenario` is plain data (pydantic, JSON round-trip). Everything the simulator
needs is in it, in physical units, and every field is validated with a message that
quotes the value that broke the rule.
"""

from __future__ import annotations

import math
import unicodedata
from itertools import combinations
from typing import Annotated, Any, Self

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

from ..checks import is_integer, number_as_written
from ..errors import InputError
from ..wording import counted

__all__ = [
    "AS_TRAINED",
    "LEVEL_ROUNDING",
    "MAX_DISTURBANCE_TORQUE_SIGMA_NM",
    "MAX_DUTY_JITTER_SIGMA",
    "MAX_GYRO_RATE_RAD_S",
    "MAX_LAG_STEPS",
    "MAX_RATE_SIGMA_RAD_S",
    "MAX_THRUST_SCALE_SIGMA",
    "CandidateGenerator",
    "InertiaCandidate",
    "Scenario",
    "Thrusters",
    "Timing",
    "Uncertainty",
    "check_inertia_tensor",
    "idle_thruster_warning",
    "idle_thrusters",
]


def _name_as_read(name: str) -> str:
    """``name`` as a reader tells it from another: NFKC-normalised (an accent composed or
    not, a full-width letter), invisible format characters (Unicode category Cf: zero-width
    space, soft hyphen, ...) dropped, white space runs as one space, trimmed."""
    visible = "".join(
        c for c in unicodedata.normalize("NFKC", name) if unicodedata.category(c) != "Cf"
    )
    return " ".join(visible.split())


# Relative tolerance for symmetry and the triangle inequality: tensors typed by hand or
# round-tripped through JSON carry rounding noise of a few ulps.
_RTOL = 1e-9


def _fmt(values: Any) -> str:
    return np.array2string(np.asarray(values, dtype=float), precision=6, separator=", ")


#: The largest inertia a candidate may state, kg m^2: ten thousand times the
#: International Space Station's (about 1e8 kg m^2), so a real spacecraft's always fits
#: and a unit slip (g m^2 or kg mm^2 typed as kg m^2) or a corrupted figure does not.
MAX_INERTIA_KG_M2 = 1e12


def check_inertia_tensor(tensor: Any) -> np.ndarray:
    """Return ``tensor`` as a (3, 3) float array if it is a physical inertia tensor.

    A physical tensor is finite, symmetric, positive definite, and its principal moments
    satisfy the triangle inequality (sorted ``p0 + p1 >= p2``). Raises
    :class:`~inertia_id.errors.InputError` naming the rule that failed and the offending
    values.
    """
    try:
        arr = np.asarray(tensor, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"inertia tensor {tensor!r} is not numeric: {exc}") from None
    if arr.shape != (3, 3):
        raise InputError(f"inertia tensor must be 3x3 (kg m^2), got shape {arr.shape}: {_fmt(arr)}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"inertia tensor has non-finite entries: {_fmt(arr)}")
    largest = float(np.max(np.abs(arr)))
    if largest > MAX_INERTIA_KG_M2:
        # Checked before the eigenvalues: 1e308 entries overflowed I + I^T ("Eigenvalues
        # did not converge"), and past about 1e150 the classifier's factors overflowed
        # ("Matrix is not positive definite" from a training job).
        raise InputError(
            f"inertia tensor has an entry of {largest:.4g} kg m^2, beyond any spacecraft "
            f"(at most {MAX_INERTIA_KG_M2:g} kg m^2; the ISS's is about 1e8): check its "
            f"units: {_fmt(arr)}"
        )
    scale = largest or 1.0
    asym = float(np.max(np.abs(arr - arr.T)))
    if asym > _RTOL * scale:
        raise InputError(
            f"inertia tensor is not symmetric (largest |I - I^T| = {asym:.3g}): {_fmt(arr)}"
        )
    moments = np.linalg.eigvalsh(0.5 * (arr + arr.T))
    if moments[0] <= 0.0:
        raise InputError(
            f"inertia tensor is not positive definite: principal moments {_fmt(moments)} kg m^2"
        )
    if moments[0] + moments[1] < moments[2] * (1.0 - _RTOL):
        raise InputError(
            "principal moments break the triangle inequality "
            f"({moments[0]:.6g} + {moments[1]:.6g} < {moments[2]:.6g}): {_fmt(moments)} kg m^2"
        )
    return 0.5 * (arr + arr.T)


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _decimal_as_written(value: Any, info: ValidationInfo) -> Any:
    return number_as_written(value, info.field_name or "value")


def _whole_as_written(value: Any, info: ValidationInfo) -> Any:
    return number_as_written(value, info.field_name or "value", whole=True)


# The number fields of a scenario document. Pydantic's lax mode, which the core keeps
# (numpy scalars and ints for floats pass), also reads "1_0" as 10, "inf" as infinity and
# true as 1 (a person's JSON file or the API's body means none of them); a string written
# as a plain decimal ("0.5") is still read, as the command line's options read it.
WrittenFloat = Annotated[float, BeforeValidator(_decimal_as_written)]
WrittenInt = Annotated[int, BeforeValidator(_whole_as_written)]


class InertiaCandidate(_Model):
    """One configuration the spacecraft may be in.

    :param name: what an operator calls this state, e.g. "payload 2 ejected".
    :param inertia_kg_m2: full 3x3 inertia tensor about the centre of mass, body frame;
        products of inertia are allowed.
    """

    name: str = Field(min_length=1, max_length=200)
    inertia_kg_m2: list[list[WrittenFloat]]

    @field_validator("inertia_kg_m2")
    @classmethod
    def _physical(cls, value: list[list[float]]) -> list[list[float]]:
        check_inertia_tensor(value)
        return value

    @property
    def principal_moments_kg_m2(self) -> np.ndarray:
        """Principal moments of inertia, ascending (kg m^2)."""
        return np.linalg.eigvalsh(np.asarray(self.inertia_kg_m2))


class CandidateGenerator(_Model):
    """The paper's payload deployer: ``I_n = I0 - dI_n``.

    Each variation removes, per body axis, a fraction of the base tensor's diagonal
    moment drawn uniformly in ``reduction_range``. The base tensor itself is the first
    candidate ("none ejected"). Seeded, so the same generator gives the same candidates.

    :param base_inertia_kg_m2: I0, the tensor with every payload aboard.
    :param n_variations: how many payload states besides the base one.
    :param reduction_range: (low, high) fraction of each diagonal moment removed.
    :param seed: seed of the draws, so that a scenario can be regenerated exactly.
    """

    base_inertia_kg_m2: list[list[WrittenFloat]]
    n_variations: WrittenInt = Field(ge=1, le=100)
    reduction_range: tuple[WrittenFloat, WrittenFloat] = (0.05, 0.15)
    seed: WrittenInt = 0
    base_name: str = "none ejected"
    variation_name: str = "payload {n} ejected"

    @field_validator("base_inertia_kg_m2")
    @classmethod
    def _physical(cls, value: list[list[float]]) -> list[list[float]]:
        check_inertia_tensor(value)
        return value

    @field_validator("reduction_range")
    @classmethod
    def _range(cls, value: tuple[float, float]) -> tuple[float, float]:
        low, high = value
        if not (0.0 <= low <= high < 1.0):
            raise InputError(
                f"reduction_range must satisfy 0 <= low <= high < 1, got {list(value)}"
            )
        return value

    def generate(self) -> list[InertiaCandidate]:
        base = np.asarray(self.base_inertia_kg_m2, dtype=float)
        rng = np.random.default_rng(self.seed)
        low, high = self.reduction_range
        candidates = [InertiaCandidate(name=self.base_name, inertia_kg_m2=base.tolist())]
        for n in range(1, self.n_variations + 1):
            reduction = rng.uniform(low, high, size=3) * np.diag(base)
            tensor = base - np.diag(reduction)
            # Only {n} is replaced: str.format would also read fields ({0}, {x}) and
            # format specs ({n:>99999999}) from a document a user wrote.
            name = self.variation_name.replace("{n}", str(n))
            try:
                candidates.append(InertiaCandidate(name=name, inertia_kg_m2=tensor.tolist()))
            except ValueError as exc:
                raise InputError(f"generated candidate {name!r} is not physical: {exc}") from None
        return candidates


#: The largest mass flow a thruster may state at full duty, kg/s: past a launcher's
#: first-stage engine (an F-1 burned about 2,600 kg/s), so no attitude thruster, only a
#: unit slip or a corrupted figure, reaches it, and a plan's propellant stays finite.
MAX_MASS_FLOW_KG_S = 1e4


def _expand_per_thruster(data: dict[str, Any]) -> dict[str, Any]:
    """A single number for ``thrust_n`` or ``lever_arm_m`` means the same for every thruster."""
    matrix = data.get("torque_matrix_nm")
    for name in ("thrust_n", "lever_arm_m"):
        value = data.get(name)
        if isinstance(value, int | float) and not isinstance(value, bool):
            if isinstance(matrix, list) and matrix and isinstance(matrix[0], list):
                data[name] = [float(value)] * len(matrix[0])
    return data


#: A thruster whose torque at full duty is at most this fraction of the largest one's
#: gives no torque (its thrust through the centre of mass; the rest is rounding).
IDLE_TORQUE_FRACTION = 1e-9


def idle_thrusters(torque_matrix: Any) -> list[int]:
    """The thrusters (indices from 0) whose column of ``torque_matrix`` (3 x N, N m) is
    zero, within :data:`IDLE_TORQUE_FRACTION` of the largest: each gives no torque, its
    lever arm parallel to its force (its thrust through the centre of mass)."""
    sizes = np.linalg.norm(np.asarray(torque_matrix, dtype=float), axis=0)
    largest = max(float(sizes.max(initial=0.0)), 1e-300)
    return [j for j, size in enumerate(sizes.tolist()) if size <= IDLE_TORQUE_FRACTION * largest]


def idle_thruster_warning(torque_matrix: Any) -> str | None:
    """A sentence naming the thrusters (numbered from 1, as a plan and the dashboard
    number them) that give no torque (:func:`idle_thrusters`); None when every one gives
    some. Not a refusal: such a thruster is allowed, but is likely a mistake (a column
    typed as zeros, a lever arm along the force)."""
    idle = [j + 1 for j in idle_thrusters(torque_matrix)]
    if not idle:
        return None
    names = ", ".join(map(str, idle[:-1])) + (" and " if len(idle) > 1 else "") + str(idle[-1])
    one = len(idle) == 1
    return (
        f"thruster{'' if one else 's'} {names} give{'s' if one else ''} no torque "
        f"(column{'' if one else 's'} {names} of torque_matrix_nm "
        f"{'is' if one else 'are'} zero: the thrust passes through the centre of mass); "
        "no search fires such a thruster, and a plan that fires one warns of it"
    )


#: How far a duty may lie from a level and still be that level: the last bits of a level
#: computed another way. Scenarios of ``n_levels`` held numpy.linspace's duties
#: (0.30000000000000004 for 0.3 at 11 levels) until their levels became i / (M - 1), and
#: searches, plans and stored scenarios of then still hold them.
LEVEL_ROUNDING = 1e-12


class Thrusters(_Model):
    """Thruster torques, the duty levels a step may command, and what firing costs.

    Give either ``torque_matrix_nm`` (3 x N, the body torque of each thruster at full
    duty, N m) or ``nominal_torque_nm`` for the paper's ``A = T [I3, -I3]``; and either
    ``levels`` or ``n_levels`` (M evenly spaced duty values from 0 to 1). After
    validation both the matrix and the levels are always filled in.

    Propellant (all optional): the thrust of each thruster at full duty, ``thrust_n``
    (N), or its effective lever arm ``lever_arm_m`` (m: the distance from the centre of
    mass to the thrust's line of action, ``|r × f̂|``, not to the thruster; the thrust is
    then ``|A_j| / lever_arm``), not both; and the specific impulse ``specific_impulse_s`` (s).
    With a thrust and a specific impulse the propellant of a sequence is
    ``Σ_j thrust_j · on_time_j / (Isp · g0)`` kg (:meth:`Scenario.propellant_kg`). A single
    number for ``thrust_n`` or ``lever_arm_m`` applies to every thruster.
    """

    torque_matrix_nm: list[list[WrittenFloat]]
    levels: list[WrittenFloat]
    thrust_n: list[WrittenFloat] | None = None
    lever_arm_m: list[WrittenFloat] | None = None
    specific_impulse_s: WrittenFloat | None = None
    standard_gravity_m_s2: WrittenFloat = 9.80665

    @model_validator(mode="before")
    @classmethod
    def _expand(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        data = dict(data)
        nominal = data.pop("nominal_torque_nm", None)
        if data.get("torque_matrix_nm") is None:
            if nominal is None:
                raise InputError("give torque_matrix_nm (3 x N, N m) or nominal_torque_nm")
            try:
                torque = float(number_as_written(nominal, "nominal_torque_nm"))
            except (TypeError, ValueError, OverflowError):
                raise InputError(f"nominal_torque_nm must be a number, got {nominal!r}") from None
            if not (math.isfinite(torque) and torque > 0):
                raise InputError(f"nominal_torque_nm must be finite and > 0, got {nominal!r}")
            data["torque_matrix_nm"] = (torque * np.hstack([np.eye(3), -np.eye(3)])).tolist()
        elif nominal is not None:
            raise InputError("give torque_matrix_nm or nominal_torque_nm, not both")
        n_levels = data.pop("n_levels", None)
        if data.get("levels") is None:
            if n_levels is None:
                raise InputError("give levels (duty values in [0, 1]) or n_levels")
            if not is_integer(n_levels, minimum=2, maximum=101, numpy=False):
                # Checked before the levels are generated: a huge count would allocate them.
                raise InputError(f"n_levels must be an integer from 2 to 101, got {n_levels!r}")
            # i / (M - 1), the double nearest each fraction: numpy.linspace steps by
            # 1 / (M - 1) and made duties of 0.30000000000000004 (M = 11), which a
            # command plan writes as a step's duty.
            data["levels"] = [i / (n_levels - 1) for i in range(n_levels)]
        elif n_levels is not None and len(data["levels"]) != n_levels:
            raise InputError(
                f"n_levels = {n_levels!r} disagrees with {counted(len(data['levels']), 'level')} "
                "given"
            )
        return _expand_per_thruster(data)

    @field_validator("torque_matrix_nm")
    @classmethod
    def _matrix(cls, value: list[list[float]]) -> list[list[float]]:
        lengths = [len(row) for row in value]
        if len(value) != 3 or len(set(lengths)) != 1 or lengths[0] < 1:
            raise InputError(
                f"torque_matrix_nm must be 3 x N with N >= 1, got rows of lengths {lengths}"
            )
        arr = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise InputError(f"torque_matrix_nm has non-finite entries: {_fmt(arr)}")
        if arr.shape[1] > 64:
            raise InputError(f"torque_matrix_nm has {arr.shape[1]} thrusters; at most 64")
        if not np.any(arr):
            raise InputError("torque_matrix_nm is all zeros: no thruster gives any torque")
        return value

    @model_validator(mode="after")
    def _propulsion(self) -> Self:
        n = len(self.torque_matrix_nm[0])
        if self.thrust_n is not None and self.lever_arm_m is not None:
            raise InputError(
                "give thrust_n or lever_arm_m (the thrust is then |A_j| / lever_arm), not both"
            )
        for name in ("thrust_n", "lever_arm_m"):
            values = getattr(self, name)
            if values is None:
                continue
            if len(values) != n:
                raise InputError(f"{name} must hold one value per thruster ({n}), got {values}")
            if not all(math.isfinite(v) and v > 0 for v in values):
                raise InputError(f"{name} must be finite and > 0 for every thruster, got {values}")
        isp = self.specific_impulse_s
        if isp is not None and not (math.isfinite(isp) and 0 < isp <= 1e6):
            raise InputError(f"specific_impulse_s must be finite and in (0, 1e6], got {isp!r}")
        g0 = self.standard_gravity_m_s2
        if not (math.isfinite(g0) and g0 > 0):
            raise InputError(f"standard_gravity_m_s2 must be finite and > 0, got {g0!r}")
        self._check_mass_flow()
        return self

    def _check_mass_flow(self) -> None:
        """Refuse a thrust, specific impulse and g0 whose mass flow at full duty is past
        :data:`MAX_MASS_FLOW_KG_S`: a thrust of 1e308 N made a plan's propellant
        infinite (``Infinity`` in its JSON, which no strict JSON reader takes), a specific
        impulse or g0 of 1e-300 one of 1e299 kg."""
        isp = self.specific_impulse_s
        if isp is None:
            return
        if self.thrust_n is not None:
            thrust, stated = np.asarray(self.thrust_n, dtype=float), "thrust_n"
        elif self.lever_arm_m is not None:
            torque = np.linalg.norm(np.asarray(self.torque_matrix_nm, dtype=float), axis=0)
            thrust = torque / np.asarray(self.lever_arm_m, dtype=float)
            stated = "thrust |A_j| / lever_arm_m"
        else:
            return
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            flow = thrust / isp / self.standard_gravity_m_s2
        worst = float(np.max(flow))
        if not (math.isfinite(worst) and worst <= MAX_MASS_FLOW_KG_S):
            raise InputError(
                f"a thruster burns {worst:.4g} kg/s at full duty ({stated} = "
                f"{float(np.max(thrust)):.4g} N / (specific_impulse_s = {isp:.4g} s x "
                f"standard_gravity_m_s2 = {self.standard_gravity_m_s2:.4g} m/s^2)): beyond "
                f"any attitude thruster (at most {MAX_MASS_FLOW_KG_S:g} kg/s); check the "
                "units of the thrust, specific impulse and g0"
            )

    @field_validator("levels")
    @classmethod
    def _levels(cls, value: list[float]) -> list[float]:
        arr = np.asarray(value, dtype=float)
        if arr.size < 2 or arr.size > 101:
            raise InputError(f"levels must hold 2 to 101 duty values, got {value}")
        if not np.all(np.isfinite(arr)) or arr.min() < 0.0 or arr.max() > 1.0:
            raise InputError(f"levels must lie within [0, 1], got {value}")
        if np.any(np.diff(arr) <= 0.0):
            raise InputError(f"levels must be strictly increasing, got {value}")
        if arr[0] != 0.0 or arr[-1] != 1.0:
            raise InputError(f"levels must include 0 and 1, got {value}")
        return value


class Timing(_Model):
    """When things happen.

    :param step_duration_s: length of one actuation step (one row of a sequence), s.
    :param integration_step_s: RK4 step, s; must divide the step duration.
    :param sample_rate_hz: gyro telemetry rate; its period must be a whole number of
        integration steps and divide the step duration.
    """

    step_duration_s: WrittenFloat = Field(default=1.0, gt=0, le=3600)
    integration_step_s: WrittenFloat = Field(default=0.05, gt=0)
    sample_rate_hz: WrittenFloat = Field(default=20.0, gt=0)

    @model_validator(mode="after")
    def _commensurate(self) -> Self:
        try:
            self._check_commensurate()
        except ArithmeticError:
            # Ratios of extreme values overflow or divide by an underflowed zero.
            raise InputError(
                f"timing out of range: step_duration_s = {self.step_duration_s}, "
                f"integration_step_s = {self.integration_step_s}, "
                f"sample_rate_hz = {self.sample_rate_hz}"
            ) from None
        return self

    def _check_commensurate(self) -> None:
        _whole(
            self.step_duration_s / self.integration_step_s,
            f"step_duration_s = {self.step_duration_s} is not a whole number of "
            f"integration_step_s = {self.integration_step_s}",
        )
        _whole(
            1.0 / (self.sample_rate_hz * self.integration_step_s),
            f"the sample period 1/sample_rate_hz = {1.0 / self.sample_rate_hz:.6g} s is "
            f"not a whole number of integration_step_s = {self.integration_step_s}",
        )
        _whole(
            self.step_duration_s * self.sample_rate_hz,
            f"step_duration_s = {self.step_duration_s} is not a whole number of sample "
            f"periods at sample_rate_hz = {self.sample_rate_hz}",
        )
        if self.substeps_per_step > 100_000:
            # In the ratio's own digits: integration_step_s = 1e-300 wrote a 301-digit count.
            raise InputError(
                f"step_duration_s / integration_step_s = {self.step_duration_s:g} / "
                f"{self.integration_step_s:g} = "
                f"{self.step_duration_s / self.integration_step_s:.4g} integration steps per "
                "actuation step is too many (at most 100,000)"
            )

    @property
    def substeps_per_step(self) -> int:
        return round(self.step_duration_s / self.integration_step_s)

    @property
    def samples_per_step(self) -> int:
        return round(self.step_duration_s * self.sample_rate_hz)

    @property
    def substeps_per_sample(self) -> int:
        return round(1.0 / (self.sample_rate_hz * self.integration_step_s))


#: The shortest actuation lag a scenario may have, in integration steps: RK4 on the lag
#: diverges past 2.78 steps a time constant (:meth:`Scenario._lag_resolved`).
LAG_STEPS_PER_TAU = 2.0


def _shown(value: Any, limit: int = 200) -> str:
    """``repr(value)``, cut at ``limit`` characters: an error names a bad sequence without
    echoing megabytes of it back."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _holds_a_bool(value: Any) -> bool:
    """Whether a (nested) list or tuple holds a bool anywhere."""
    if isinstance(value, (bool, np.bool_)):
        return True
    if isinstance(value, (list, tuple)):
        return any(_holds_a_bool(item) for item in value)
    return False


def _whole(ratio: float, message: str) -> None:
    if not math.isfinite(ratio) or ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
        raise InputError(message)


#: The largest body rate an attitude gyro measures, rad/s (5,730 deg/s, some 16 turns a
#: second): a rate past it is beyond any attitude gyro's range, a corrupted word or a unit
#: slip rather than attitude motion. The one ceiling on telemetry
#: (:data:`inertia_id.evaluation.telemetry.MAX_TELEMETRY_RATE_RAD_S`), on a scenario's
#: noise figures (below) and on the rates a command plan or a response predicts
#: (:func:`inertia_id.physics.simulate.check_gyro_range`).
MAX_GYRO_RATE_RAD_S = 100.0
#: Largest gyro noise, bias or initial-rate spread a scenario may state, rad/s: the
#: largest rate a gyro measures.
MAX_RATE_SIGMA_RAD_S = MAX_GYRO_RATE_RAD_S
#: Largest duty jitter a scenario may state, in full duties. The delivered duty is
#: clipped to [0, 1]: at a sigma of 10 a firing thruster's delivered duty lands inside
#: (0, 1) in about 4 % of its steps and is otherwise off or full, a coin flip rather than
#: the timing jitter of a valve (a real one is a few percent of a duty). Past it a figure
#: means nothing more (1e308 overflowed its draws to infinities, then clipped).
MAX_DUTY_JITTER_SIGMA = 10.0
#: Largest relative thrust-scale (calibration) error a scenario may state. A thruster's
#: torque is scaled by 1 + sigma z, z standard normal, and no thruster pushes backwards:
#: at 0.5 one draw in 44 (z < -2) already reverses a thruster, at 1 one in 6. At 0.5 a
#: noise sweep's largest multiple (1000) still simulates the paper preset (rates up to
#: 180 rad/s; at 700 they overflow).
MAX_THRUST_SCALE_SIGMA = 0.5
#: Largest disturbance torque sigma a scenario may state, N m per axis: more than ten
#: times the torque of the Space Shuttle's primary RCS, among the largest attitude
#: thrusters flown (3.9 kN on lever arms of about 10 to 20 m, some 4e4 to 8e4 N m),
#: while the environment's torques (gravity gradient, drag, solar pressure) are far
#: smaller still.
#: Past it lies a unit slip or a corrupted figure: 1e308 overflowed the draws, and its
#: square (the noise model's covariance) was infinite from about 1e154.
MAX_DISTURBANCE_TORQUE_SIGMA_NM = 1e6
#: Longest actuation lag a scenario may state, in actuation steps (``step_duration_s``).
#: A first-order lag of time constant tau delivers, within a step of T from rest, the
#: fraction 1 - (tau / T)(1 - exp(-T / tau)) of the torque commanded: 0.5 % at tau =
#: 100 T. Past it the thrusters barely respond within a sequence and the body drifts
#: under noise alone (1e308 s trained to 0.425 accuracy, without a word).
MAX_LAG_STEPS = 100.0


#: Each bounded noise figure's bound, unit and the refusal's reason (``{bound}`` is the
#: bound), in :class:`Uncertainty`'s one validator for them.
_NOISE_BOUNDS: dict[str, tuple[float, str, str]] = {
    "duty_jitter_sigma": (
        MAX_DUTY_JITTER_SIGMA,
        "(fraction of full duty)",
        "is no thruster's timing jitter: at most {bound:g} full duties (the delivered duty "
        "is clipped to [0, 1], so past a few full duties each step is a coin flip between "
        "off and full)",
    ),
    "thrust_scale_sigma": (
        MAX_THRUST_SCALE_SIGMA,
        "(fraction of nominal torque)",
        "is no calibration error: at most {bound:g} (each thruster's torque is scaled by "
        "1 + sigma z, z standard normal; at 0.5 one draw in 44 already reverses a thruster, "
        "and no thruster pushes backwards)",
    ),
    "disturbance_torque_sigma_nm": (
        MAX_DISTURBANCE_TORQUE_SIGMA_NM,
        "N m",
        "is beyond any spacecraft's disturbance: at most {bound:g} N m (more than ten times "
        "the torque of the Space Shuttle's primary RCS thrusters, some 4e4 to 8e4 N m); "
        "check its units",
    ),
}


#: The validation context of a scenario a classifier was trained on, read back from its
#: document (``Scenario.model_validate(data, context=AS_TRAINED)``): the bounds on what a
#: person may state (:data:`_NOISE_BOUNDS`, :data:`MAX_LAG_STEPS`) came after classifiers
#: were stored, and a classifier trained on a scenario past them is kept usable as it
#: was trained (its figures are its provenance, not a new statement). Every other rule
#: holds: a figure that cannot be simulated is refused all the same.
AS_TRAINED: dict[str, bool] = {"as_trained": True}


def _as_trained(info: ValidationInfo) -> bool:
    return bool(info.context and info.context.get("as_trained"))


#: The sigmas a noise sweep scales (:data:`inertia_id.evaluation.sweep.NOISE_FIELDS`),
#: which :meth:`Scenario.with_swept_noise` may set past what a scenario may state.
SWEPT_SIGMAS = (
    "duty_jitter_sigma",
    "thrust_scale_sigma",
    "disturbance_torque_sigma_nm",
    "gyro_noise_sigma_rad_s",
    "gyro_bias_sigma_rad_s",
)


class Uncertainty(_Model):
    """Every source of randomness, in physical units; each can be zero.

    :param duty_jitter_sigma: standard deviation of the duty actually delivered by a
        firing thruster around the commanded level (fraction of full duty), redrawn each
        step; the paper's response-time variance. Delivered duty is clipped to [0, 1].
        At most :data:`MAX_DUTY_JITTER_SIGMA`.
    :param lowpass_time_constant_s: first-order lag between commanded and applied torque
        (valve and chamber dynamics); 0 applies torque instantly. At most
        :data:`MAX_LAG_STEPS` actuation steps (checked by :class:`Scenario`).
    :param thrust_scale_sigma: relative error of each thruster's torque, drawn once per
        realisation (calibration error; torque and inertia enter Euler's equations as a
        ratio, so this is the confounder that matters most). At most
        :data:`MAX_THRUST_SCALE_SIGMA`.
    :param disturbance_torque_sigma_nm: process noise, a random torque per body axis (N m),
        piecewise constant, redrawn every ``disturbance_interval_s``. At most
        :data:`MAX_DISTURBANCE_TORQUE_SIGMA_NM`.
    :param gyro_noise_sigma_rad_s: white gyro noise per axis and sample (rad/s).
    :param gyro_bias_rad_s: constant gyro bias vector (rad/s).
    :param gyro_bias_sigma_rad_s: random constant bias per realisation and axis (rad/s);
        default 2e-3, what an uncalibrated MEMS gyro carries between calibrations.
    :param initial_rate_sigma_rad_s: spread of the angular velocity at the start (rad/s);
        default 5e-3, a spacecraft left drifting after detumbling; 0 starts every
        realisation at rest.
    """

    duty_jitter_sigma: WrittenFloat = Field(default=0.02, ge=0)
    lowpass_time_constant_s: WrittenFloat = Field(default=0.1, ge=0)
    thrust_scale_sigma: WrittenFloat = Field(default=0.0, ge=0)
    disturbance_torque_sigma_nm: WrittenFloat = Field(default=0.05, ge=0)
    disturbance_interval_s: WrittenFloat = Field(default=0.05, gt=0)
    gyro_noise_sigma_rad_s: WrittenFloat = Field(default=1e-3, ge=0)
    gyro_bias_rad_s: tuple[WrittenFloat, WrittenFloat, WrittenFloat] = (0.0, 0.0, 0.0)
    gyro_bias_sigma_rad_s: WrittenFloat = Field(default=2e-3, ge=0)
    initial_rate_sigma_rad_s: WrittenFloat = Field(default=5e-3, ge=0)

    @field_validator("*", mode="after")
    @classmethod
    def _finite(cls, value: Any, info: Any) -> Any:
        values = value if isinstance(value, tuple) else (value,)
        if not all(math.isfinite(float(v)) for v in values):
            raise InputError(f"{info.field_name} must be finite, got {value!r}")
        return value

    @field_validator(*_NOISE_BOUNDS, mode="after")
    @classmethod
    def _a_figure_of_a_real_spacecraft(cls, value: float, info: ValidationInfo) -> float:
        bound, unit, why = _NOISE_BOUNDS[info.field_name or ""]
        if value > bound and not _as_trained(info):
            raise InputError(f"{info.field_name} = {value!r} {unit} {why.format(bound=bound)}")
        return value

    @field_validator(
        "gyro_noise_sigma_rad_s",
        "gyro_bias_rad_s",
        "gyro_bias_sigma_rad_s",
        "initial_rate_sigma_rad_s",
        mode="after",
    )
    @classmethod
    def _a_rate_a_gyro_reads(cls, value: Any, info: Any) -> Any:
        # A rate beyond any gyro's range is no noise of one: a sigma of 1e300 rad/s was
        # simulated, then overflowed a classifier's covariance (inf, then "array must not
        # contain infs or NaNs" at training, with no name).
        values = value if isinstance(value, tuple) else (value,)
        if any(abs(float(v)) > MAX_RATE_SIGMA_RAD_S for v in values):
            raise InputError(
                f"{info.field_name} = {value!r} rad/s is beyond any attitude gyro's range: "
                f"at most {MAX_RATE_SIGMA_RAD_S:g} rad/s "
                f"({math.degrees(MAX_RATE_SIGMA_RAD_S):,.0f} deg/s)"
            )
        return value


class Scenario(_Model):
    """A spacecraft, its possible configurations, and how it is driven and observed.

    Give ``inertia_candidates`` explicitly, or a ``candidate_generator`` (the paper's
    payload deployer) which is expanded into explicit candidates on validation and kept
    for provenance.
    """

    name: str = Field(default="custom", min_length=1, max_length=200)
    inertia_candidates: list[InertiaCandidate]
    candidate_generator: CandidateGenerator | None = None
    thrusters: Thrusters
    timing: Timing = Timing()
    uncertainty: Uncertainty = Uncertainty()

    @model_validator(mode="before")
    @classmethod
    def _generate(cls, data: Any) -> Any:
        if isinstance(data, dict) and not data.get("inertia_candidates"):
            generator = data.get("candidate_generator")
            if generator is None:
                raise InputError("give inertia_candidates or a candidate_generator")
            if not isinstance(generator, CandidateGenerator):
                generator = CandidateGenerator.model_validate(generator)
            data = {**data, "inertia_candidates": generator.generate()}
        return data

    @field_validator("inertia_candidates")
    @classmethod
    def _candidates(cls, value: list[InertiaCandidate]) -> list[InertiaCandidate]:
        if not 2 <= len(value) <= 100:
            raise InputError(f"need 2 to 100 inertia candidates, got {len(value)}")
        names = [c.name for c in value]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise InputError(f"candidate names must be unique; repeated: {duplicates}")
        # Names are what an operator reads in a plan's columns and a verdict: two that
        # read the same ("café" in one code point or two, "stowed" and "stowed" with a
        # zero-width space) or one that shows nothing ("   ") name no candidate. Case is
        # seen, and kept: "Stowed" and "stowed" stay two names.
        seen: dict[str, str] = {}
        for name in names:
            read = _name_as_read(name)
            if not read:
                raise InputError(
                    f"candidate name {name!r} shows nothing (white space or invisible "
                    "characters only); give each candidate a visible name"
                )
            if read in seen:
                raise InputError(
                    f"candidate names must read differently: {seen[read]!r} and {name!r} "
                    "read the same (Unicode normalisation NFKC, white space and invisible "
                    "characters aside)"
                )
            seen[read] = name
        return value

    def check_distinguishable(self) -> None:
        """Refuse candidates with the same tensor: no rate response tells them apart, so
        a classifier of them cannot be trained (a scenario holding them is still valid,
        as the two-body scenarios a sweep of bodies off the candidates builds).

        :raises InputError: naming the first such pair.
        """
        candidates = self.inertia_candidates
        tensors = [np.asarray(c.inertia_kg_m2, dtype=float) for c in candidates]
        for i, j in combinations(range(len(candidates)), 2):
            if np.array_equal(tensors[i], tensors[j]):
                raise InputError(
                    f"candidates {candidates[i].name!r} and {candidates[j].name!r} have the "
                    "same inertia tensor: no rate response tells them apart"
                )

    @model_validator(mode="after")
    def _disturbance_grid(self) -> Self:
        dt = self.timing.integration_step_s
        interval = self.uncertainty.disturbance_interval_s
        _whole(
            interval / dt,
            f"disturbance_interval_s = {interval} is not a whole number of "
            f"integration_step_s = {dt}",
        )
        _whole(
            self.timing.step_duration_s / interval,
            f"step_duration_s = {self.timing.step_duration_s} is not a whole number of "
            f"disturbance_interval_s = {interval}",
        )
        return self

    @model_validator(mode="after")
    def _lag_resolved(self, info: ValidationInfo) -> Self:
        # RK4 on the lag dm/dt = (c - m) / tau is stable only while dt <= 2.78 tau;
        # beyond it the applied torque, and every rate, grows without bound (NaN).
        # Refused at dt > 2 tau, a margin short of that edge.
        dt = self.timing.integration_step_s
        tau = self.uncertainty.lowpass_time_constant_s
        step = self.timing.step_duration_s
        if tau > MAX_LAG_STEPS * step and not _as_trained(info):
            # A time constant of 100 steps delivers 0.5 % of a step's commanded torque
            # within it (MAX_LAG_STEPS): the thrusters never answer their commands.
            raise InputError(
                f"lowpass_time_constant_s = {tau!r} s is an actuation lag of "
                f"{tau / step:.12g} steps of step_duration_s = {step:g} s: at most "
                f"{MAX_LAG_STEPS:g} steps ({MAX_LAG_STEPS * step:g} s), where a step "
                "already delivers only 0.5 % of the torque it commands (the thrusters "
                "would barely respond and the body drift under noise alone)"
            )
        if 0.0 < tau < dt / LAG_STEPS_PER_TAU:
            raise InputError(
                f"lowpass_time_constant_s = {tau} is too short for integration_step_s = "
                f"{dt}: RK4 on the actuation lag diverges once a step exceeds 2.78 lag "
                f"time constants; give lowpass_time_constant_s >= {dt / LAG_STEPS_PER_TAU:g}"
                " (0 for no lag) or a smaller integration_step_s"
            )
        return self

    # Arrays the numerical code works with.

    @property
    def candidate_names(self) -> list[str]:
        return [c.name for c in self.inertia_candidates]

    @property
    def inertia_array(self) -> np.ndarray:
        """Inertia tensors, shape (K, 3, 3), kg m^2."""
        return np.array([c.inertia_kg_m2 for c in self.inertia_candidates], dtype=float)

    @property
    def torque_matrix(self) -> np.ndarray:
        """Thruster torque matrix A, shape (3, N), N m at full duty."""
        return np.asarray(self.thrusters.torque_matrix_nm, dtype=float)

    @property
    def idle_thrusters(self) -> list[int]:
        """The thrusters (from 0) that give no torque (:func:`idle_thrusters`)."""
        return idle_thrusters(self.torque_matrix)

    @property
    def level_values(self) -> np.ndarray:
        """Duty level of each level index, shape (M,)."""
        return np.asarray(self.thrusters.levels, dtype=float)

    @property
    def n_candidates(self) -> int:
        return len(self.inertia_candidates)

    @property
    def n_thrusters(self) -> int:
        return len(self.thrusters.torque_matrix_nm[0])

    @property
    def n_levels(self) -> int:
        return len(self.thrusters.levels)

    def sample_times(self, n_steps: int) -> np.ndarray:
        """Telemetry time stamps (s from the start of the sequence) for ``n_steps`` steps.

        Samples are taken at the end of each sample period, so the first is at
        ``1 / sample_rate_hz`` and the last at the end of the sequence.
        """
        n = n_steps * self.timing.samples_per_step
        return np.arange(1, n + 1) / self.timing.sample_rate_hz

    def check_sequence(self, sequence: Any) -> np.ndarray:
        """Return ``sequence`` as an (L, N) integer array of level indices, or raise.

        A sequence row gives, for each thruster, the index into ``thrusters.levels`` of
        the duty it fires at during that step.
        """
        try:
            arr = np.asarray(sequence)
        except (TypeError, ValueError):
            raise InputError(
                f"sequence {_shown(sequence)} is not an array of level indices"
            ) from None
        if _holds_a_bool(sequence):
            # numpy reads [4, true] as [4, 1]: a JSON true must not fire level 1.
            raise InputError(f"sequence must hold integer level indices, got {_shown(sequence)}")
        if arr.ndim == 1 and arr.size == self.n_thrusters:
            arr = arr[None, :]
        if arr.ndim != 2 or arr.shape[1] != self.n_thrusters or arr.shape[0] < 1:
            raise InputError(
                f"sequence must be L x {self.n_thrusters} level indices (one per thruster), "
                f"got shape {arr.shape}"
            )
        if arr.shape[0] > 1000:
            raise InputError(f"sequence has {arr.shape[0]} steps; at most 1000")
        if not np.issubdtype(arr.dtype, np.number) or not np.all(np.isfinite(arr)):
            raise InputError(
                f"sequence must hold integer level indices, got {_shown(arr.tolist())}"
            )
        as_int = arr.astype(int)
        if np.any(as_int != arr):
            raise InputError(
                f"sequence must hold integer level indices, got {_shown(arr.tolist())}"
            )
        bad = (as_int < 0) | (as_int >= self.n_levels)
        if np.any(bad):
            step, thruster = (int(i) for i in np.argwhere(bad)[0])
            # Numbered from 1, as every table, plan and report numbers steps and thrusters.
            raise InputError(
                f"sequence step {step + 1}, thruster {thruster + 1}: level index "
                f"{as_int[step, thruster]} is outside 0..{self.n_levels - 1}"
            )
        return as_int

    def check_fires(self, sequence: Any) -> np.ndarray:
        """Return ``sequence`` as :meth:`check_sequence` does, or refuse one that applies
        no torque at any step: every level index at duty 0, or firings whose torques
        cancel at every step. The body then only drifts under noise, whose spread alone
        differs between candidates (the disturbance's random walk scales with I⁻¹: the
        noise model's classifier read 0.216-0.218 on a one-thruster scenario's five candidates,
        chance 0.2), so nothing commanded tells them apart and no classifier is trained on
        it (a search may still score it: it is the zero-impulse end of a front).

        :raises InputError: saying which.
        """
        rows = self.check_sequence(sequence)
        duties = self.level_values[rows]
        if not np.any(duties > 0.0):
            raise InputError(
                f"sequence {_shown(rows.tolist())} fires no thruster at any step (every "
                "level index is duty 0): the body only drifts under noise, so nothing "
                "commanded tells the candidates apart (their drift differs only by the "
                "noise's spread, near chance); no classifier is trained on it"
            )
        torque = duties @ self.torque_matrix.T  # (L, 3), N m
        scale = float(np.max(np.abs(self.torque_matrix)))
        if np.all(np.abs(torque) <= 1e-9 * scale):
            raise InputError(
                f"sequence {_shown(rows.tolist())} applies no net torque at any step (its "
                "thrusters' torques cancel): the body only drifts under noise, so nothing "
                "commanded tells the candidates apart (their drift differs only by the "
                "noise's spread, near chance); no classifier is trained on it"
            )
        return rows

    def duties(self, sequence: Any) -> np.ndarray:
        """Commanded duty of each thruster at each step, shape (L, N), in [0, 1]."""
        return self.level_values[self.check_sequence(sequence)]

    def impulse_nms(self, sequence: Any) -> float:
        """Commanded angular impulse of a sequence, summed over thrusters, N m s.

        Each thruster contributes ``|A_j| · duty · step duration`` on every step it fires,
        whatever the others do: two opposing thrusters fired together cost both their
        impulses although their torques cancel. It is a propellant proxy (proportional to
        propellant mass when every thruster has the same thrust, lever arm and specific
        impulse), not the net angular impulse the body receives.
        """
        per_thruster = np.linalg.norm(self.torque_matrix, axis=0)
        return float(self.on_time_s(sequence) @ per_thruster)

    def on_time_s(self, sequence: Any) -> np.ndarray:
        """Total on-time of each thruster over a sequence, (N,) s: duty x step duration,
        summed over the steps (the PWM on-time a flight team commands)."""
        return np.asarray(self.duties(sequence).sum(axis=0) * self.timing.step_duration_s)

    @property
    def thrust_per_thruster_n(self) -> np.ndarray | None:
        """Thrust of each thruster at full duty, (N,) N, when the scenario says it:
        ``thrust_n``, or ``|A_j| / lever_arm_m``; else None."""
        thrusters = self.thrusters
        if thrusters.thrust_n is not None:
            return np.asarray(thrusters.thrust_n, dtype=float)
        if thrusters.lever_arm_m is not None:
            torque = np.linalg.norm(self.torque_matrix, axis=0)
            return np.asarray(torque / np.asarray(thrusters.lever_arm_m, dtype=float))
        return None

    @property
    def propellant_unstated(self) -> str | None:
        """Why :meth:`propellant_kg` is None, naming the thruster fields that would state
        it; None when the scenario states it."""
        missing = []
        if self.thrust_per_thruster_n is None:
            missing.append("thrust_n (or lever_arm_m)")
        if self.thrusters.specific_impulse_s is None:
            missing.append("specific_impulse_s")
        if not missing:
            return None
        return f"the scenario's thrusters give no {' and no '.join(missing)}"

    @property
    def propellant_basis(self) -> str | None:
        """How :meth:`propellant_kg` is reached from the fields the scenario gives (its
        thrust from ``thrust_n`` or from the lever arms); None when it is not stated."""
        if self.propellant_unstated is not None:
            return None
        thrust = (
            "thrust_n" if self.thrusters.thrust_n is not None else "thrust (|A_j| / lever_arm_m)"
        )
        return (
            f"sum over thrusters of {thrust} x on-time / "
            "(specific_impulse_s x standard_gravity_m_s2), kg"
        )

    def propellant_kg(self, sequence: Any) -> float | None:
        """Propellant mass a sequence burns, kg: ``Σ_j F_j t_j / (Isp g0)``, counting every
        thruster's on-time (opposing thrusters both burn); None unless the scenario gives
        a thrust (or lever arms) and a specific impulse."""
        thrust = self.thrust_per_thruster_n
        isp = self.thrusters.specific_impulse_s
        if thrust is None or isp is None:
            return None
        exhaust_velocity = isp * self.thrusters.standard_gravity_m_s2
        return float(self.on_time_s(sequence) @ thrust / exhaust_velocity)

    def duration_s(self, sequence: Any) -> float:
        """How long a sequence lasts, s."""
        return float(len(self.check_sequence(sequence)) * self.timing.step_duration_s)

    def with_swept_noise(self, **levels: float) -> Scenario:
        """A copy with some noise sigmas at the levels a noise sweep visits: a multiple
        (at most :data:`~inertia_id.evaluation.sweep.MAX_MULTIPLE`, 1000) of a level the
        scenario states or of a reference level, so past what a scenario may state.

        Not validated again, unlike :meth:`with_uncertainty`: the bounds on a sigma are
        on what a person states, and a sweep at 1000x of a sigma at its bound was
        refused in the middle of its job. The rules that span fields (the disturbance
        interval on the grid, the lag against the steps) involve no sigma.

        :raises InputError: for a field that is no sigma a sweep scales, or a level
            that is not finite and >= 0.
        """
        unknown = sorted(set(levels) - set(SWEPT_SIGMAS))
        if unknown:
            raise InputError(f"a sweep scales {list(SWEPT_SIGMAS)}, not {unknown}")
        bad = {k: v for k, v in levels.items() if not (math.isfinite(v) and v >= 0.0)}
        if bad:
            raise InputError(f"swept noise levels must be finite and >= 0, got {bad}")
        noise = self.uncertainty.model_copy(update={k: float(v) for k, v in levels.items()})
        return self.model_copy(update={"uncertainty": noise})

    def same_spacecraft(self, other: Scenario) -> bool:
        """Whether ``other`` differs from this scenario in its name alone, or in its duty
        levels by no more than :data:`LEVEL_ROUNDING` each: a sequence's level indices
        fly the same duties on both."""
        ours, theirs = self.thrusters.levels, other.thrusters.levels
        if len(ours) == len(theirs) and all(
            abs(a - b) <= LEVEL_ROUNDING for a, b in zip(ours, theirs, strict=True)
        ):
            thrusters = self.thrusters.model_copy(update={"levels": list(theirs)})
            mine = self.model_copy(update={"name": other.name, "thrusters": thrusters})
            return mine == other
        return False

    def with_uncertainty(self, **changes: Any) -> Scenario:
        """A copy with some uncertainty fields changed (validated)."""
        # Validate the whole scenario again: some rules (the disturbance interval on the
        # integration grid) span the uncertainty and the timing.
        uncertainty = {**self.uncertainty.model_dump(), **changes}
        return type(self).model_validate({**self.model_dump(), "uncertainty": uncertainty})

    @classmethod
    def paper(cls) -> Scenario:
        """The paper's payload-deployer spacecraft (the "paper" preset)."""
        from .presets import preset

        return preset("paper")
