"""Scenario data: presets, generation, JSON round trip and validation messages."""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np
import pydantic
import pytest
from scenario_support import I0

from inertia_id import (
    PRESETS,
    CandidateGenerator,
    InertiaCandidate,
    Scenario,
    Thrusters,
    Timing,
    Uncertainty,
    check_inertia_tensor,
    preset,
)

WITH_PRODUCTS = [[50.0, 3.0, -2.0], [3.0, 30.0, 1.0], [-2.0, 1.0, 45.0]]


def paper_data(**changes: Any) -> dict[str, Any]:
    data = Scenario.paper().model_dump()
    data.update(changes)
    return data


# JSON round trip.


def test_paper_json_round_trip(paper: Scenario) -> None:
    text = paper.model_dump_json()
    again = Scenario.model_validate_json(text)
    assert again == paper
    assert again.model_dump_json() == text
    np.testing.assert_array_equal(again.inertia_array, paper.inertia_array)


def test_custom_json_round_trip_keeps_every_field() -> None:
    scenario = Scenario.model_validate(
        {
            "name": "odd one",
            "inertia_candidates": [
                {"name": "α", "inertia_kg_m2": WITH_PRODUCTS},
                {"name": "β", "inertia_kg_m2": (0.9 * np.asarray(WITH_PRODUCTS)).tolist()},
            ],
            "thrusters": {
                "torque_matrix_nm": [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]],
                "levels": [0.0, 0.1, 1.0],
            },
            "timing": {"step_duration_s": 0.5, "integration_step_s": 0.025, "sample_rate_hz": 10},
            "uncertainty": {
                "thrust_scale_sigma": 0.1,
                "gyro_bias_rad_s": [1e-3, 0.0, -1e-3],
                "disturbance_interval_s": 0.1,
                "initial_rate_sigma_rad_s": 1e-2,
            },
        }
    )
    again = Scenario.model_validate_json(scenario.model_dump_json())
    assert again == scenario
    assert again.uncertainty.gyro_bias_rad_s == (1e-3, 0.0, -1e-3)
    assert again.candidate_names == ["α", "β"]


# The paper preset.


def test_paper_preset_values(paper: Scenario) -> None:
    assert paper.name == "paper"
    assert paper.n_candidates == 5
    assert paper.n_thrusters == 6
    assert paper.n_levels == 5
    np.testing.assert_array_equal(paper.inertia_array[0], I0)
    assert paper.candidate_names == ["none ejected"] + [f"payload {n} ejected" for n in range(1, 5)]
    # A = T [I3, -I3] with T = 2 N m.
    np.testing.assert_array_equal(paper.torque_matrix, 2.0 * np.hstack([np.eye(3), -np.eye(3)]))
    np.testing.assert_array_equal(paper.level_values, [0.0, 0.25, 0.5, 0.75, 1.0])
    assert paper.timing.step_duration_s == 1.0
    assert paper.timing.samples_per_step == 20
    assert paper.timing.substeps_per_step == 20
    for tensor in paper.inertia_array[1:]:
        # I_n = I0 - dI_n: only the diagonal changes, by 5 to 15 % per axis.
        np.testing.assert_array_equal(tensor - np.diag(np.diag(tensor)), 0.0)
        reduction = 1.0 - np.diag(tensor) / np.diag(I0)
        assert np.all((reduction >= 0.05) & (reduction <= 0.15)), reduction
    # All candidates differ and are physical.
    tensors = paper.inertia_array
    for i in range(5):
        check_inertia_tensor(tensors[i])
        for j in range(i):
            assert np.abs(tensors[i] - tensors[j]).max() > 0.5
    # "paper" is the paper's premise (at rest, unbiased gyro); "paper-in-orbit" is the
    # same spacecraft with the drift a real one has, the Uncertainty defaults.
    assert paper == Scenario.paper() == preset("paper")
    assert paper.uncertainty.initial_rate_sigma_rad_s == 0.0
    assert paper.uncertainty.gyro_bias_sigma_rad_s == 0.0
    orbit = preset("paper-in-orbit")
    assert orbit.uncertainty.initial_rate_sigma_rad_s == Uncertainty().initial_rate_sigma_rad_s
    assert orbit.uncertainty.gyro_bias_sigma_rad_s == Uncertainty().gyro_bias_sigma_rad_s
    assert Uncertainty().initial_rate_sigma_rad_s == 5e-3
    assert Uncertainty().gyro_bias_sigma_rad_s == 2e-3
    assert orbit.with_uncertainty(initial_rate_sigma_rad_s=0.0, gyro_bias_sigma_rad_s=0.0) == (
        paper.model_copy(update={"name": "paper-in-orbit"})
    )
    assert sorted(PRESETS) == ["paper", "paper-in-orbit"]


def test_generator_is_seeded_and_reproducible() -> None:
    gen = CandidateGenerator(base_inertia_kg_m2=WITH_PRODUCTS, n_variations=6, seed=3)
    first, second = gen.generate(), gen.generate()
    assert first == second
    assert len(first) == 7
    np.testing.assert_array_equal(first[0].inertia_kg_m2, WITH_PRODUCTS)
    other = CandidateGenerator(base_inertia_kg_m2=WITH_PRODUCTS, n_variations=6, seed=4).generate()
    assert [c.inertia_kg_m2 for c in other[1:]] != [c.inertia_kg_m2 for c in first[1:]]
    base = np.asarray(WITH_PRODUCTS)
    for candidate in first[1:]:
        tensor = np.asarray(candidate.inertia_kg_m2)
        off = ~np.eye(3, dtype=bool)
        np.testing.assert_array_equal(tensor[off], base[off])  # products kept
        reduction = 1.0 - np.diag(tensor) / np.diag(base)
        assert np.all((reduction >= 0.05) & (reduction <= 0.15))
    # A degenerate range removes exactly that fraction.
    exact = CandidateGenerator(
        base_inertia_kg_m2=I0.tolist(), n_variations=1, reduction_range=(0.1, 0.1)
    ).generate()
    np.testing.assert_allclose(exact[1].inertia_kg_m2, 0.9 * I0, rtol=1e-15)
    # A scenario built from the same generator twice is the same scenario.
    thrusters = {"nominal_torque_nm": 1.0, "n_levels": 3}
    s1 = Scenario.model_validate({"candidate_generator": gen.model_dump(), "thrusters": thrusters})
    s2 = Scenario.model_validate({"candidate_generator": gen.model_dump(), "thrusters": thrusters})
    assert s1 == s2 and s1.n_candidates == 7


def test_generator_rejects_unphysical_results() -> None:
    # A body on the edge of the triangle inequality (60 + 50 = 110): removing more from
    # the small moments than from the large one makes it unphysical.
    with pytest.raises(
        ValueError,
        match=r"(?s)generated candidate 'payload 1 ejected' is not "
        r"physical: .*triangle inequality \(42\.8917 \+ 47\.8376 < 93\.1099\)",
    ):
        CandidateGenerator(
            base_inertia_kg_m2=np.diag([110.0, 60.0, 50.0]).tolist(),
            n_variations=3,
            reduction_range=(0.0, 0.3),
            seed=1,
        ).generate()
    with pytest.raises(pydantic.ValidationError, match=r"0 <= low <= high < 1, got \[0\.2, 0\.1\]"):
        CandidateGenerator(
            base_inertia_kg_m2=I0.tolist(), n_variations=2, reduction_range=(0.2, 0.1)
        )


# Inertia tensor validation.


@pytest.mark.parametrize(
    ("tensor", "match"),
    [
        ([[100, 1, 0], [0, 60, 0], [0, 0, 90]], r"not symmetric \(largest \|I - I\^T\| = 1\)"),
        (
            np.diag([100, -60, 90]),
            r"not positive definite: principal moments \[-60\., +90\., +100\.\]",
        ),
        (np.diag([0, 60, 90]), r"not positive definite"),
        (np.diag([10, 10, 30]), r"triangle inequality \(10 \+ 10 < 30\): \[10\., 10\., 30\.\]"),
        ([[1, 2], [3, 4]], r"must be 3x3 .*got shape \(2, 2\)"),
        (np.eye(4), r"must be 3x3 .*got shape \(4, 4\)"),
        ([[np.nan, 0, 0], [0, 60, 0], [0, 0, 90]], r"non-finite entries: \[\[ *nan"),
        ([[np.inf, 0, 0], [0, 60, 0], [0, 0, 90]], r"non-finite entries"),
        ("abc", r"'abc' is not numeric"),
        # Past any spacecraft: 1e308 was refused as "Eigenvalues did not converge", and
        # 1e200 taken, its training job failing on "Matrix is not positive definite".
        (np.diag([1e308, 1e308, 1e308]), r"an entry of 1e\+308 kg m\^2, beyond any spacecraft"),
        (np.diag([1e200, 1e200, 1e200]), r"entry of 1e\+200 kg m\^2.*at most 1e\+12"),
    ],
)
def test_bad_inertia_tensors_are_rejected(tensor: Any, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        check_inertia_tensor(tensor)
    if isinstance(tensor, str):
        return  # pydantic rejects a string before the tensor check runs
    # The pydantic models report the same message.
    value = np.asarray(tensor).tolist()
    with pytest.raises(pydantic.ValidationError, match=match):
        InertiaCandidate(name="x", inertia_kg_m2=value)


def test_the_largest_spacecraft_inertia_is_taken() -> None:
    """The bound is far past a real spacecraft's: ten thousand ISS (about 1e8 kg m^2)."""
    assert check_inertia_tensor(np.diag([1e12, 0.9e12, 0.8e12]))[0, 0] == 1e12


def test_triangle_inequality_in_a_rotated_frame() -> None:
    # Principal moments (10, 15, 30) in a rotated frame: the diagonal alone hides it.
    c, s = np.cos(0.4), np.sin(0.4)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array(
        [[1, 0, 0], [0, c, -s], [0, s, c]]
    )
    tensor = rot @ np.diag([10.0, 15.0, 30.0]) @ rot.T
    with pytest.raises(ValueError, match=r"\(10 \+ 15 < 30\)"):
        check_inertia_tensor(tensor)


def test_physical_edge_cases_are_accepted() -> None:
    # A thin flat plate sits exactly on the triangle inequality.
    np.testing.assert_allclose(check_inertia_tensor(np.diag([1.0, 2.0, 3.0])), np.diag([1, 2, 3]))
    # Rounding-level asymmetry is accepted and symmetrised.
    tensor = np.array(WITH_PRODUCTS)
    tensor[0, 1] += 1e-12
    out = check_inertia_tensor(tensor)
    np.testing.assert_array_equal(out, out.T)


# Thrusters.


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (
            {"nominal_torque_nm": 2.0, "levels": [0, 0.5, 0.4, 1]},
            r"strictly increasing, got \[0\.0, 0\.5, 0\.4, 1\.0\]",
        ),
        ({"nominal_torque_nm": 2.0, "levels": [0, 0.5, 0.5, 1]}, r"strictly increasing"),
        (
            {"nominal_torque_nm": 2.0, "levels": [0, 0.5, 1.2]},
            r"within \[0, 1\], got \[0\.0, 0\.5, 1\.2\]",
        ),
        ({"nominal_torque_nm": 2.0, "levels": [-0.1, 0.5, 1]}, r"within \[0, 1\], got \[-0\.1"),
        (
            {"nominal_torque_nm": 2.0, "levels": [0.1, 0.5, 1.0]},
            r"include 0 and 1, got \[0\.1, 0\.5, 1\.0\]",
        ),
        ({"nominal_torque_nm": 2.0, "levels": [0.0, 0.5]}, r"include 0 and 1, got \[0\.0, 0\.5\]"),
        ({"nominal_torque_nm": 2.0, "levels": [1.0]}, r"2 to 101 duty values, got \[1\.0\]"),
        ({"nominal_torque_nm": 2.0, "n_levels": 1}, r"n_levels must be an integer from 2 to 101"),
        (
            {"nominal_torque_nm": 2.0, "levels": [0, 1], "n_levels": 3},
            r"n_levels = 3 disagrees with 2",
        ),
        (
            {"nominal_torque_nm": 2.0, "levels": [1.0], "n_levels": 3},
            r"n_levels = 3 disagrees with 1 level given",
        ),
        ({"torque_matrix_nm": [[1, 2], [3, 4]], "n_levels": 2}, r"3 x N .*lengths \[2, 2\]"),
        (
            {"torque_matrix_nm": [[1, 2], [3], [4, 5]], "n_levels": 2},
            r"3 x N .*lengths \[2, 1, 2\]",
        ),
        ({"torque_matrix_nm": [[], [], []], "n_levels": 2}, r"3 x N with N >= 1, .*\[0, 0, 0\]"),
        ({"torque_matrix_nm": [[1.0], [np.nan], [0.0]], "n_levels": 2}, r"non-finite entries"),
        (
            {"torque_matrix_nm": [[1.0], [0.0], [0.0]], "nominal_torque_nm": 2.0, "n_levels": 2},
            r"not both",
        ),
        ({"n_levels": 2}, r"give torque_matrix_nm \(3 x N, N m\) or nominal_torque_nm"),
        ({"nominal_torque_nm": 2.0}, r"give levels"),
        ({"nominal_torque_nm": -2.0, "n_levels": 2}, r"finite and > 0, got -2\.0"),
        ({"nominal_torque_nm": "two", "n_levels": 2}, r"must be a number, got 'two'"),
    ],
)
def test_bad_thrusters_are_rejected(data: dict[str, Any], match: str) -> None:
    with pytest.raises(pydantic.ValidationError, match=match):
        Thrusters.model_validate(data)


def test_thrusters_expand_nominal_and_n_levels() -> None:
    thrusters = Thrusters.model_validate({"nominal_torque_nm": 0.5, "n_levels": 3})
    np.testing.assert_array_equal(
        thrusters.torque_matrix_nm, 0.5 * np.hstack([np.eye(3), -np.eye(3)])
    )
    assert thrusters.levels == [0.0, 0.5, 1.0]


@pytest.mark.parametrize("value", ["1_0", "\uff12\uff10", "inf", True, "0x14"])
def test_a_number_not_as_written_is_refused_by_name(value: Any) -> None:
    """Pydantic's lax mode read "1_0" as 10 and true as 1 in a scenario file."""
    shown = re.escape(repr(value))
    with pytest.raises(
        pydantic.ValidationError, match=rf"sample_rate_hz must be a decimal .*{shown}"
    ):
        Timing.model_validate({"sample_rate_hz": value})
    with pytest.raises(pydantic.ValidationError, match=rf"seed must be a whole number .*{shown}"):
        CandidateGenerator.model_validate(
            {"base_inertia_kg_m2": I0, "n_variations": 2, "seed": value}
        )
    with pytest.raises(
        pydantic.ValidationError, match=rf"nominal_torque_nm must be a number, got {shown}"
    ):
        Thrusters.model_validate({"nominal_torque_nm": value, "n_levels": 3})


def test_a_number_as_written_is_read_from_a_string_as_before() -> None:
    timing = Timing.model_validate(
        {"sample_rate_hz": " 10 ", "step_duration_s": np.float64(2.0), "integration_step_s": 0.05}
    )
    assert (timing.sample_rate_hz, timing.step_duration_s) == (10.0, 2.0)
    generator = CandidateGenerator.model_validate(
        {"base_inertia_kg_m2": I0, "n_variations": "2", "seed": np.int64(3)}
    )
    assert (generator.n_variations, generator.seed) == (2, 3)


# Uncertainty and timing.


@pytest.mark.parametrize(
    "field",
    [
        "duty_jitter_sigma",
        "lowpass_time_constant_s",
        "thrust_scale_sigma",
        "disturbance_torque_sigma_nm",
        "gyro_noise_sigma_rad_s",
        "gyro_bias_sigma_rad_s",
        "initial_rate_sigma_rad_s",
    ],
)
def test_negative_sigmas_are_rejected(field: str) -> None:
    with pytest.raises(
        pydantic.ValidationError,
        match=rf"{field}\n.*greater than or equal to 0"
        r".*input_value=-0\.25",
    ):
        Uncertainty.model_validate({field: -0.25})
    with pytest.raises(pydantic.ValidationError, match=rf"{field} must be finite, got inf"):
        Uncertainty.model_validate({field: float("inf")})


def test_non_finite_bias_is_rejected() -> None:
    with pytest.raises(
        pydantic.ValidationError, match=r"gyro_bias_rad_s must be finite, got \(0\.0, nan"
    ):
        Uncertainty(gyro_bias_rad_s=(0.0, float("nan"), 0.0))


@pytest.mark.parametrize(
    ("model", "data", "match"),
    [
        (Timing, {"step_duration_s": 0.0}, r"step_duration_s\n.*greater than 0.*input_value=0\.0"),
        (
            Timing,
            {"step_duration_s": -1.0},
            r"step_duration_s\n.*greater than 0.*input_value=-1\.0",
        ),
        (Timing, {"integration_step_s": 0.0}, r"integration_step_s\n.*greater than 0"),
        (Timing, {"sample_rate_hz": -20.0}, r"sample_rate_hz\n.*greater than 0"),
        (Uncertainty, {"disturbance_interval_s": 0.0}, r"disturbance_interval_s\n.*greater than 0"),
    ],
)
def test_non_positive_durations_are_rejected(
    model: type[pydantic.BaseModel], data: dict[str, Any], match: str
) -> None:
    with pytest.raises(pydantic.ValidationError, match=match):
        model.model_validate(data)


@pytest.mark.parametrize(
    ("timing", "match"),
    [
        (
            {"step_duration_s": 1.0, "integration_step_s": 0.3},
            r"step_duration_s = 1\.0 is not a whole number of integration_step_s = 0\.3",
        ),
        ({"integration_step_s": 2.0}, r"not a whole number of integration_step_s = 2\.0"),
        (
            {"sample_rate_hz": 30.0},
            r"sample period 1/sample_rate_hz = 0\.0333333 s is not a whole number of "
            r"integration_step_s = 0\.05",
        ),
        ({"sample_rate_hz": 40.0}, r"sample period .* = 0\.025 s is not a whole number"),
        (
            {"step_duration_s": 1.025, "integration_step_s": 0.025},
            r"step_duration_s = 1\.025 is not a whole number of sample periods at "
            r"sample_rate_hz = 20\.0",
        ),
    ],
)
def test_incommensurate_timing_is_rejected(timing: dict[str, Any], match: str) -> None:
    with pytest.raises(pydantic.ValidationError, match=match):
        Timing.model_validate(timing)


def test_too_many_integration_steps_are_refused_in_few_digits() -> None:
    """An integration step of 1e-300 s was refused with the count written out in 301
    digits."""
    with pytest.raises(pydantic.ValidationError) as refused:
        Timing.model_validate({"integration_step_s": 1e-300})
    message = str(refused.value)
    assert "integration_step_s = 1 / 1e-300 = 1e+300 integration steps per actuation step" in (
        message
    )
    assert "0" * 20 not in message


def test_timing_derived_counts() -> None:
    timing = Timing(step_duration_s=0.5, integration_step_s=0.025, sample_rate_hz=10.0)
    assert (timing.substeps_per_step, timing.samples_per_step, timing.substeps_per_sample) == (
        20,
        5,
        4,
    )
    # Values that are whole only up to float rounding are accepted.
    Timing(step_duration_s=0.3, integration_step_s=0.1, sample_rate_hz=10.0)


@pytest.mark.parametrize(
    ("interval", "match"),
    [
        (
            0.07,
            r"disturbance_interval_s = 0\.07 is not a whole number of integration_step_s = 0\.05",
        ),
        (0.3, r"step_duration_s = 1\.0 is not a whole number of disturbance_interval_s = 0\.3"),
        (0.02, r"disturbance_interval_s = 0\.02 is not a whole number"),
    ],
)
def test_disturbance_interval_must_fit_the_grid(interval: float, match: str) -> None:
    data = paper_data()
    data["uncertainty"]["disturbance_interval_s"] = interval
    with pytest.raises(pydantic.ValidationError, match=match):
        Scenario.model_validate(data)


def test_an_actuation_lag_shorter_than_rk4_resolves_is_refused() -> None:
    """RK4 on the lag diverges once a step exceeds 2.78 time constants: every rate turns
    NaN (silently, in the compiled simulator). Such a lag is refused, naming both values
    and the shortest one allowed; at the limit, or with no lag, the simulation is finite."""
    from inertia_id import Simulator

    data = paper_data()  # integration_step_s 0.05
    data["uncertainty"]["lowpass_time_constant_s"] = 0.01
    with pytest.raises(
        pydantic.ValidationError,
        match=r"lowpass_time_constant_s = 0\.01 is too short for integration_step_s = 0\.05"
        r".*lowpass_time_constant_s >= 0\.025",
    ):
        Scenario.model_validate(data)
    for tau in (0.025, 0.0):
        data["uncertainty"]["lowpass_time_constant_s"] = tau
        scenario = Scenario.model_validate(data)
        simulator = Simulator(scenario, 2)
        run = simulator.run(
            np.array([[4, 4, 4, 0, 0, 0]] * 2),
            simulator.draw_noise(np.random.default_rng(0), 2),
        )
        assert np.isfinite(run.omega_true).all()
    # Just past the limit the old behaviour shows: the rates blow up.
    from inertia_id.physics.dynamics import RigidBodies

    bodies = RigidBodies(inertia=np.eye(3)[None] * 100.0, dt=0.05, tau=0.05 / 2.9)
    omega, torque = np.zeros((1, 1, 3)), np.zeros((1, 1, 3))
    _, applied, _, _ = bodies.run(
        omega,
        torque,
        np.ones((1, 1, 3)),
        np.zeros((1, 1, 1, 3)),
        substeps=200,
        per_interval=200,
        per_sample=200,
    )
    assert not np.isfinite(applied).all() or np.abs(applied).max() > 1e6


# Scenario-level rules.
# Scenario-level rules.


def test_duplicate_candidate_names_are_rejected() -> None:
    data = paper_data()
    data["inertia_candidates"][3]["name"] = data["inertia_candidates"][1]["name"]
    with pytest.raises(
        pydantic.ValidationError, match=r"names must be unique; repeated: \['payload 1 ejected'\]"
    ):
        Scenario.model_validate(data)


@pytest.mark.parametrize(
    ("first", "second"),
    [
        ("caf\u00e9", "cafe\u0301"),  # é as one code point, and as e with a combining accent
        ("stowed", "stowed\u200b"),  # a zero-width space after it
        ("boom deployed", "boom  deployed "),  # white space
        ("payload 1", "payload \uff11"),  # a full-width digit one
    ],
)
def test_candidate_names_that_read_the_same_are_rejected(first: str, second: str) -> None:
    # Before: stored as two candidates that a plan's columns, a verdict and
    # `simulate --candidate` showed alike (found by a hostile review of the service).
    data = paper_data()
    data["inertia_candidates"][0]["name"] = first
    data["inertia_candidates"][2]["name"] = second
    with pytest.raises(pydantic.ValidationError, match="candidate names must read differently"):
        Scenario.model_validate(data)


@pytest.mark.parametrize("name", ["   ", "\u200b", "\u00ad\u2060"])
def test_a_candidate_name_that_shows_nothing_is_rejected(name: str) -> None:
    data = paper_data()
    data["inertia_candidates"][1]["name"] = name
    with pytest.raises(pydantic.ValidationError, match="shows nothing"):
        Scenario.model_validate(data)


def test_candidate_count_and_presence_rules() -> None:
    data = paper_data()
    data["inertia_candidates"] = data["inertia_candidates"][:1]
    with pytest.raises(pydantic.ValidationError, match="need 2 to 100 inertia candidates, got 1"):
        Scenario.model_validate(data)
    data = paper_data(inertia_candidates=[], candidate_generator=None)
    with pytest.raises(
        pydantic.ValidationError, match="give inertia_candidates or a candidate_generator"
    ):
        Scenario.model_validate(data)
    with pytest.raises(pydantic.ValidationError, match=r"bogus\n.*Extra inputs are not permitted"):
        Scenario.model_validate(paper_data(bogus=1))


def test_scenario_is_frozen(paper: Scenario) -> None:
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        paper.name = "changed"  # type: ignore[misc]


# Presets and copies.


def test_preset_overrides() -> None:
    # Nested dicts are merged into the preset's, so the rest is kept.
    quieter = preset("paper", uncertainty={"gyro_noise_sigma_rad_s": 2e-3})
    assert quieter.uncertainty.gyro_noise_sigma_rad_s == 2e-3
    assert quieter.uncertainty.disturbance_torque_sigma_nm == 0.05
    assert quieter.uncertainty.lowpass_time_constant_s == 0.1

    faster = preset("paper", timing={"sample_rate_hz": 10.0})
    assert faster.timing.samples_per_step == 10 and faster.timing.integration_step_s == 0.05

    fewer_levels = preset("paper", thrusters={"levels": [0.0, 0.5, 1.0]})
    assert fewer_levels.n_levels == 3
    np.testing.assert_array_equal(fewer_levels.torque_matrix, Scenario.paper().torque_matrix)

    # A new generator regenerates the candidates.
    regenerated = preset("paper", candidate_generator={"n_variations": 2, "seed": 5})
    assert regenerated.n_candidates == 3
    np.testing.assert_array_equal(regenerated.inertia_array[0], I0)
    assert not np.array_equal(regenerated.inertia_array[1], Scenario.paper().inertia_array[1])

    # Overrides are validated like any input.
    with pytest.raises(pydantic.ValidationError, match=r"input_value=-1\.0"):
        preset("paper", uncertainty={"duty_jitter_sigma": -1.0})


def test_preset_can_override_scenario_name() -> None:
    renamed = preset("paper", name="renamed")
    assert renamed.name == "renamed"
    assert renamed.inertia_candidates == Scenario.paper().inertia_candidates


def test_unknown_preset_is_rejected() -> None:
    with pytest.raises(
        ValueError, match=r"unknown preset 'nope'; known: \['paper', 'paper-in-orbit'\]"
    ):
        preset("nope")


@pytest.mark.parametrize(
    ("override", "check"),
    [
        (
            {"nominal_torque_nm": 3.0},
            lambda s: np.testing.assert_array_equal(
                s.torque_matrix, 3.0 * np.hstack([np.eye(3), -np.eye(3)])
            ),
        ),
        ({"n_levels": 3}, lambda s: np.testing.assert_array_equal(s.level_values, [0, 0.5, 1])),
    ],
)
def test_preset_thrusters_override_in_alternative_form(
    override: dict[str, Any], check: Any
) -> None:
    check(preset("paper", thrusters=override))


def test_with_uncertainty_copies_and_validates(paper: Scenario) -> None:
    changed = paper.with_uncertainty(gyro_noise_sigma_rad_s=5e-3, thrust_scale_sigma=0.1)
    assert changed.uncertainty.gyro_noise_sigma_rad_s == 5e-3
    assert changed.uncertainty.thrust_scale_sigma == 0.1
    assert changed.uncertainty.duty_jitter_sigma == paper.uncertainty.duty_jitter_sigma
    assert changed.inertia_candidates == paper.inertia_candidates
    assert paper.uncertainty.gyro_noise_sigma_rad_s == 1e-3  # original untouched
    with pytest.raises(pydantic.ValidationError, match=r"input_value=-1"):
        paper.with_uncertainty(gyro_noise_sigma_rad_s=-1)
    with pytest.raises(pydantic.ValidationError, match="Extra inputs are not permitted"):
        paper.with_uncertainty(not_a_field=1.0)


@pytest.mark.parametrize("interval", [0.3, 0.07])
def test_with_uncertainty_validates_the_whole_scenario(paper: Scenario, interval: float) -> None:
    with pytest.raises(ValueError, match=rf"disturbance_interval_s = {interval}"):
        paper.with_uncertainty(disturbance_interval_s=interval)


# Sequence helpers.


def test_duties_and_sample_times(paper: Scenario) -> None:
    np.testing.assert_array_equal(
        paper.duties([[4, 3, 2, 1, 0, 0]]), [[1.0, 0.75, 0.5, 0.25, 0.0, 0.0]]
    )
    times = paper.sample_times(2)
    assert len(times) == 40
    assert times[0] == pytest.approx(0.05) and times[-1] == pytest.approx(2.0)
    np.testing.assert_allclose(np.diff(times), 0.05, rtol=1e-12)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (
            {
                "timing": {
                    "step_duration_s": 1.0,
                    "integration_step_s": 0.05,
                    "sample_rate_hz": 5e-324,
                }
            },
            "timing out of range",
        ),
        ({"thrusters": {"nominal_torque_nm": 10**400}}, "nominal_torque_nm must be a number"),
    ],
)
def test_extreme_numbers_are_refused_with_a_value_error(
    overrides: dict[str, Any], message: str
) -> None:
    # Overflow and underflow must surface as validation errors, not arithmetic crashes.
    with pytest.raises(ValueError, match=message):
        preset("paper", **overrides)


@pytest.mark.parametrize(
    "field", ["gyro_noise_sigma_rad_s", "gyro_bias_sigma_rad_s", "initial_rate_sigma_rad_s"]
)
def test_a_rate_sigma_beyond_any_gyro_is_refused_naming_it(field: str) -> None:
    """A gyro noise of 1e300 rad/s was simulated, then overflowed the default classifier's
    covariance at training: "array must not contain infs or NaNs", naming nothing (a
    hostile review)."""
    with pytest.raises(ValueError, match=rf"{field} = 1e\+300 rad/s is beyond any attitude gyro"):
        preset("paper", uncertainty={field: 1e300})
    with pytest.raises(ValueError, match=r"gyro_bias_rad_s = \(0.0, -101.0, 0.0\) rad/s"):
        preset("paper", uncertainty={"gyro_bias_rad_s": (0.0, -101.0, 0.0)})
    assert preset("paper", uncertainty={field: 100.0}).uncertainty.model_dump()[field] == 100.0


@pytest.mark.parametrize(
    ("field", "bound", "past", "message"),
    [
        (
            "duty_jitter_sigma",
            10.0,
            1e308,
            r"duty_jitter_sigma = 1e\+308 \(fraction of full duty\) is no thruster's timing "
            r"jitter: at most 10 full duties \(the delivered duty is clipped to \[0, 1\]",
        ),
        (
            "thrust_scale_sigma",
            0.5,
            0.51,
            r"thrust_scale_sigma = 0\.51 \(fraction of nominal torque\) is no calibration "
            r"error: at most 0\.5 .*no thruster pushes backwards",
        ),
        (
            "disturbance_torque_sigma_nm",
            1e6,
            1e308,
            r"disturbance_torque_sigma_nm = 1e\+308 N m is beyond any spacecraft's "
            r"disturbance: at most 1e\+06 N m .*check its units",
        ),
    ],
)
def test_a_noise_figure_past_any_spacecrafts_is_refused_naming_it(
    field: str, bound: float, past: float, message: str
) -> None:
    """Each was stored and a job accepted that failed later, or trained on noise alone;
    now refused where it is stated, naming the field, the value, the unit and the bound.
    At the bound it is taken."""
    with pytest.raises(pydantic.ValidationError, match=message) as refused:
        preset("paper", uncertainty={field: past})
    assert refused.value.errors()[0]["loc"] == ("uncertainty", field)
    with pytest.raises(pydantic.ValidationError, match=message):
        Uncertainty(**{field: past})
    assert getattr(preset("paper", uncertainty={field: bound}).uncertainty, field) == bound


def test_an_actuation_lag_of_more_than_100_steps_is_refused_naming_it() -> None:
    """A lag of 1e308 s was stored, trained to 0.425 accuracy without a word (the
    thrusters never answered). The bound is 100 actuation steps, however long a step."""
    data = paper_data()  # step_duration_s 1
    data["uncertainty"]["lowpass_time_constant_s"] = 1e308
    with pytest.raises(
        pydantic.ValidationError,
        match=r"lowpass_time_constant_s = 1e\+308 s is an actuation lag of 1e\+308 steps of "
        r"step_duration_s = 1 s: at most 100 steps \(100 s\), where a step already delivers "
        r"only 0\.5 % of the torque it commands",
    ):
        Scenario.model_validate(data)
    data["uncertainty"]["lowpass_time_constant_s"] = 100.0
    assert Scenario.model_validate(data).uncertainty.lowpass_time_constant_s == 100.0
    data["uncertainty"]["lowpass_time_constant_s"] = 100.5
    with pytest.raises(pydantic.ValidationError, match=r"= 100\.5 s .* 100\.5 steps"):
        Scenario.model_validate(data)
    # Steps of 10 s take a lag of 1000 s; the rule is on the steps, not the seconds.
    data["timing"]["step_duration_s"] = 10.0
    data["uncertainty"]["lowpass_time_constant_s"] = 1000.0
    assert Scenario.model_validate(data).uncertainty.lowpass_time_constant_s == 1000.0
    # What the bound says: at 100 steps a step delivers 0.5 % of the torque it commands.
    tau = 100.0
    assert 1.0 - tau * (1.0 - np.exp(-1.0 / tau)) == pytest.approx(0.005, abs=2e-5)


def test_a_sweeps_copy_may_pass_the_bounds_but_not_be_infinite() -> None:
    """A noise sweep scales a sigma up to 1000x (MAX_MULTIPLE): its copy is not
    validated again, so a scenario at its bound is swept; what it may set is a sweep's
    sigma, finite and >= 0."""
    paper = Scenario.paper()
    swept = paper.with_swept_noise(duty_jitter_sigma=1e4, thrust_scale_sigma=500.0)
    assert swept.uncertainty.duty_jitter_sigma == 1e4
    assert swept.uncertainty.thrust_scale_sigma == 500.0
    assert swept.inertia_candidates == paper.inertia_candidates
    with pytest.raises(ValueError, match=r"not \['lowpass_time_constant_s'\]"):
        paper.with_swept_noise(lowpass_time_constant_s=1.0)
    with pytest.raises(ValueError, match=r"finite and >= 0, got \{'duty_jitter_sigma': inf\}"):
        paper.with_swept_noise(duty_jitter_sigma=float("inf"))


def test_the_bounds_are_the_figures_the_readme_states() -> None:
    from inertia_id.physics import scenario

    assert scenario.MAX_DUTY_JITTER_SIGMA == 10.0
    assert scenario.MAX_THRUST_SCALE_SIGMA == 0.5
    assert scenario.MAX_DISTURBANCE_TORQUE_SIGMA_NM == 1e6
    assert scenario.MAX_LAG_STEPS == 100.0


def test_evenly_spaced_duty_levels_read_as_the_upload_writes_them() -> None:
    """``n_levels: 11`` made duty levels 0.30000000000000004, 0.6000000000000001 and
    0.7000000000000001 (0.1 x 3, as numpy.linspace steps them), which a command plan
    writes as each step's duty: each level is i / (M - 1), the double nearest the
    fraction (0.3)."""
    from inertia_id.search.plan import command_plan

    for m in (3, 5, 7, 11, 101):
        scenario = preset("paper", thrusters={"n_levels": m})
        assert scenario.thrusters.levels == [i / (m - 1) for i in range(m)]
    eleven = preset("paper", thrusters={"n_levels": 11})
    assert [repr(v) for v in eleven.thrusters.levels][3] == "0.3"
    plan = command_plan(eleven, [[3, 6, 7, 0, 0, 0]]).to_dict()
    assert json.dumps(plan["steps"][0]["duty"]) == "[0.3, 0.6, 0.7, 0.0, 0.0, 0.0]"
