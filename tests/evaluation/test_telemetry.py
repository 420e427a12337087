"""Telemetry's time base and resampling: real clocks, real rates, real gaps.

Each series is simulated at its own rate and identified by a classifier trained at the
paper's 20 Hz; the time base (mission clock, ISO stamps, a start inside the series) and
the coverage rules are exercised through :func:`identify`, as a user meets them.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
import pydantic
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import (
    InertiaClassifier,
    InputError,
    Scenario,
    Telemetry,
    identify,
    parse_telemetry,
    simulate,
)
from inertia_id.evaluation.telemetry import (
    ResponseShape,
    estimate_sequence_start,
    parse_sequence_start,
    resample,
    resample_covered,
)
from inertia_id.physics.presets import NOISE_OFF

MISSION_START_S = 810_000_123.0  # a spacecraft clock ~26 years after its epoch
UTC_START = datetime(2025, 3, 1, 12, 0, 0, tzinfo=UTC)


def at_rate(paper: Scenario, hz: float) -> Scenario:
    """The paper scenario with its gyro sampled at ``hz`` (integration step dividing it)."""
    data = paper.model_dump()
    step = 0.05 if hz <= 20 else 1.0 / hz if hz > 100 else 0.01
    data["timing"] = {"step_duration_s": 1.0, "integration_step_s": step, "sample_rate_hz": hz}
    return Scenario.model_validate(data)


def iso(offsets_s: np.ndarray, origin: datetime = UTC_START) -> list[str]:
    return [
        (origin + timedelta(microseconds=round(1e6 * s))).isoformat().replace("+00:00", "Z")
        for s in offsets_s
    ]


def assert_all_identified(
    classifier: InertiaClassifier, make: Any, result: Any, n: int = 1
) -> None:
    """``make(time_s, omega)`` builds the telemetry of each simulated series."""
    for k in range(result.omega_measured.shape[0]):
        for i in range(n):
            verdict = identify(classifier, make(result.time_s, result.omega_measured[k, i]))
            assert (verdict.candidate_index, verdict.matches_none) == (k, False), (k, i)


def plain(t: np.ndarray, w: np.ndarray, **extra: Any) -> Telemetry:
    return Telemetry(time_s=np.asarray(t).tolist(), omega_rad_s=np.asarray(w).tolist(), **extra)


# Time base.


def test_mission_clock_stamps_need_and_use_the_sequence_start(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    result = simulate(paper, GOOD_SEQUENCE, 2, np.random.default_rng(21))
    assert_all_identified(
        euclidean_classifier,
        lambda t, w: plain(t + MISSION_START_S, w, sequence_start=MISSION_START_S),
        result,
        n=2,
    )
    # The same verdict as with stamps from the start: the subtraction loses nothing.
    t, w = result.time_s, result.omega_measured[3, 0]
    mission = plain(t + MISSION_START_S, w, sequence_start=str(MISSION_START_S))
    np.testing.assert_allclose(mission.time_array, t, atol=2e-7)
    assert identify(euclidean_classifier, mission).distances == pytest.approx(
        identify(euclidean_classifier, plain(t, w)).distances, rel=1e-6
    )
    with pytest.raises(
        ValueError, match=r"sequence_start is required: .* time_s\[0\] = 810000123\.05"
    ):
        plain(t + MISSION_START_S, w)


def test_a_copy_with_a_new_start_measures_from_it_and_a_field_cannot_be_reassigned() -> None:
    """``model_copy(update=...)`` skipped validation and kept the offsets from the old
    start (a start moved 0.05 s later read the same times), and assignment left them
    stale too: a copy is now validated afresh, and a field cannot be assigned."""
    w = [[0.0, 0.0, 0.0]] * 3
    telemetry = plain(
        MISSION_START_S + np.array([0.0, 0.05, 0.1]), w, sequence_start=MISSION_START_S
    )
    moved = telemetry.model_copy(update={"sequence_start": MISSION_START_S + 0.05})
    np.testing.assert_allclose(moved.time_array, [-0.05, 0.0, 0.05], atol=2e-7)
    assert moved == telemetry.shifted(0.05) and moved != telemetry
    np.testing.assert_allclose(telemetry.time_array, [0.0, 0.05, 0.1], atol=2e-7)
    # The other fields the offsets come from: the stamps, and averaged rates.
    restamped = telemetry.model_copy(
        update={"time_s": [MISSION_START_S + 1.0, MISSION_START_S + 2.0, MISSION_START_S + 4.0]}
    )
    np.testing.assert_allclose(restamped.time_array, [1.0, 2.0, 4.0], atol=2e-7)
    averaged = telemetry.model_copy(update={"averaged": True})
    np.testing.assert_allclose(averaged.time_array, [-0.025, 0.025, 0.075], atol=2e-7)
    stamps = iso(np.array([0.0, 0.05, 0.1]))
    utc = Telemetry(time_utc=stamps, omega_rad_s=w, sequence_start=stamps[0])
    np.testing.assert_allclose(
        utc.model_copy(update={"sequence_start": stamps[2]}).time_array, [-0.1, -0.05, 0.0]
    )
    # An update is checked as a new telemetry would be, by name.
    with pytest.raises(ValueError, match=r"sequence_start = '2025-03-01T12:00:00Z' is an ISO"):
        telemetry.model_copy(update={"sequence_start": "2025-03-01T12:00:00Z"})
    with pytest.raises(ValueError, match=r"unknown key\(s\) 'sequence_star'"):
        telemetry.model_copy(update={"sequence_star": 1.0})
    with pytest.raises(pydantic.ValidationError, match="frozen"):
        telemetry.sequence_start = MISSION_START_S + 0.05  # type: ignore[misc]
    np.testing.assert_allclose(telemetry.time_array, [0.0, 0.05, 0.1], atol=2e-7)
    assert telemetry.model_copy() == telemetry


def test_the_stamps_and_rates_cannot_be_changed_in_place() -> None:
    """Frozen stopped assignment, but the fields were lists: ``time_s.append(...)`` or
    ``omega_rad_s[0][0] = ...`` changed the telemetry under the offsets the validator
    had derived (four stamps, three offsets). They are tuples now; a list or a JSON
    array is still what goes in, and a JSON array what comes out."""
    stamps, rates = [0.0, 0.05, 0.1], [[0.0, 0.0, 0.0], [0.1, 0.2, 0.3], [0.0, 0.0, 0.0]]
    telemetry = plain(np.array(stamps), rates)
    with pytest.raises(AttributeError):
        telemetry.time_s.append(0.15)  # type: ignore[union-attr]
    with pytest.raises(TypeError):
        telemetry.omega_rad_s[1][0] = 5.0  # type: ignore[index]
    with pytest.raises(AttributeError):
        telemetry.omega_rad_s.append([0.0, 0.0, 0.0])  # type: ignore[attr-defined]
    utc_stamps = iso(np.array(stamps))
    utc = Telemetry(time_utc=utc_stamps, omega_rad_s=rates, sequence_start=utc_stamps[0])
    with pytest.raises(AttributeError):
        utc.time_utc.append(utc_stamps[0])  # type: ignore[union-attr]
    # The caller's lists are not the telemetry's either.
    given = {"time_s": list(stamps), "omega_rad_s": [list(r) for r in rates]}
    kept = Telemetry.model_validate(given)
    given["time_s"].append(0.15)
    given["omega_rad_s"][1][0] = 5.0
    assert len(kept.time_s or ()) == len(kept.time_array) == 3
    np.testing.assert_array_equal(kept.omega_array, rates)
    assert kept == telemetry
    # In and out as JSON arrays, as before.
    assert json.loads(kept.model_dump_json())["omega_rad_s"] == rates
    assert kept.model_dump(mode="json")["time_s"] == stamps
    assert Telemetry.model_validate_json(kept.model_dump_json()) == kept


def test_iso_stamps_in_json_and_csv(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    result = simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(22))
    start = UTC_START.isoformat().replace("+00:00", "Z")
    assert_all_identified(
        euclidean_classifier,
        lambda t, w: Telemetry(time_utc=iso(t), omega_rad_s=w.tolist(), sequence_start=start),
        result,
    )
    t, w = result.time_s, result.omega_measured[2, 0]
    rows = [f"{s},{a!r},{b!r},{c!r}" for s, (a, b, c) in zip(iso(t), w.tolist(), strict=True)]
    for header in (["time_utc,wx,wy,wz"], []):
        parsed = parse_telemetry("\n".join(header + rows), sequence_start=start)
        np.testing.assert_allclose(parsed.time_array, t, atol=1e-9)
        assert identify(euclidean_classifier, parsed).candidate_index == 2
    # Strings in time_s are ISO stamps too; an offset other than Z is converted to UTC.
    later = UTC_START + timedelta(hours=2)
    shifted = Telemetry(
        time_s=[s.replace("Z", "+02:00") for s in iso(t, later)],
        omega_rad_s=w.tolist(),
        sequence_start=start,
    )
    np.testing.assert_allclose(shifted.time_array, t, atol=1e-9)


def test_rfc3339_lower_case_t_and_z_are_taken_as_the_capitals() -> None:
    """RFC 3339 (5.6) allows "t" and "z"; they were refused as "not an ISO-8601 UTC time
    stamp" (Python's fromisoformat takes the capitals only)."""
    upper = ["2025-03-01T12:00:00Z", "2025-03-01T12:00:00.050Z", "2025-03-01T12:00:00.100Z"]
    lower = [s.replace("T", "t").replace("Z", "z") for s in upper]
    rates = [[0.0, 0.0, 0.0]] * 3
    expected = Telemetry(time_utc=upper, omega_rad_s=rates, sequence_start=upper[0])
    for stamps, start in ((lower, upper[0]), (upper, lower[0]), (lower, lower[0])):
        got = Telemetry(time_utc=stamps, omega_rad_s=rates, sequence_start=start)
        np.testing.assert_array_equal(got.time_array, expected.time_array)
    parsed = parse_telemetry(
        "\n".join(f"{s},0,0,0" for s in lower), sequence_start="2025-03-01t12:00:00z"
    )
    np.testing.assert_array_equal(parsed.time_array, expected.time_array)
    assert parse_sequence_start(" 2025-03-01t12:00:00z ") == "2025-03-01T12:00:00Z"
    # Only the separator and the zone: other letters are still refused, by name.
    with pytest.raises(pydantic.ValidationError, match=r"time_utc\[1\] = '2025-03-01x12:00:00z'"):
        Telemetry(
            time_utc=[upper[0], "2025-03-01x12:00:00z"],
            omega_rad_s=rates[:2],
            sequence_start=upper[0],
        )


def test_iso_8601_ordinal_dates_the_day_of_the_year_are_read() -> None:
    """ISO 8601's ordinal date (``2026-341T12:00:00Z``: CCSDS's ASCII time code B, the
    day of the year in which ground segments stamp telemetry) was refused as "neither
    seconds nor an ISO-8601 UTC stamp" (Python's fromisoformat does not read it), and so
    was a sequence start written that way."""
    calendar = ["2024-12-31T23:59:59.950Z", "2025-01-01T00:00:00Z", "2025-01-01T00:00:00.050Z"]
    ordinal = ["2024-366T23:59:59.950Z", "2025-001T00:00:00Z", "2025001T000000.050Z"]
    rates = [[0.0, 0.0, 0.0]] * 3
    expected = Telemetry(time_utc=calendar, omega_rad_s=rates, sequence_start=calendar[1])
    np.testing.assert_allclose(expected.time_array, [-0.05, 0.0, 0.05], atol=1e-12)
    for stamps, start in ((ordinal, calendar[1]), (calendar, ordinal[1]), (ordinal, ordinal[1])):
        got = Telemetry(time_utc=stamps, omega_rad_s=rates, sequence_start=start)
        np.testing.assert_array_equal(got.time_array, expected.time_array)
    text = "\n".join(f"{s},0,0,0" for s in ordinal)
    for header in ("time_utc,wx,wy,wz\n", ""):
        parsed = parse_telemetry(header + text, sequence_start="2025-001T00:00:00Z")
        np.testing.assert_array_equal(parsed.time_array, expected.time_array)
    # Passed on as Python's datetime reads it (simulate --time-offset, a stored verdict).
    assert parse_sequence_start("2026-341t12:00:00z") == "2026-12-07T12:00:00Z"
    assert parse_sequence_start("2026341T120000Z") == "2026-12-07T120000Z"
    # A day the year does not have is still refused, as written.
    for start in ("2025-366T00:00:00Z", "2025-000T00:00:00Z", "9999-366T00:00:00Z"):
        with pytest.raises(InputError, match=rf"sequence_start = '{start}' is not an ISO-8601"):
            parse_sequence_start(start)


@pytest.mark.parametrize(
    ("data", "match"),
    [
        (
            {"time_utc": ["2025-03-01T12:00:00Z", "2025-03-01T12:00:01Z"]},
            r"sequence_start is required with ISO-8601 stamps "
            r"\(time_utc\[0\] = '2025-03-01T12:00:00Z'\)",
        ),
        (
            {
                "time_utc": ["2025-03-01T12:00:00", "2025-03-01T12:00:01"],
                "sequence_start": "2025-03-01T12:00:00Z",
            },
            r"time_utc\[0\] = '2025-03-01T12:00:00' has no time zone",
        ),
        (
            {
                "time_utc": ["2025-03-01T12:00:00Z", "noon"],
                "sequence_start": "2025-03-01T12:00:00Z",
            },
            r"time_utc\[1\] = 'noon' is not an ISO-8601 UTC time stamp",
        ),
        (
            {
                "time_utc": ["2025-03-01T12:00:01Z", "2025-03-01T12:00:01Z"],
                "sequence_start": "2025-03-01T12:00:00Z",
            },
            r"increase strictly: time_utc\[0\] = '2025-03-01T12:00:01Z', time_utc\[1\] = "
            r"'2025-03-01T12:00:01Z': the same stamp twice \(a sample sent twice\?\)",
        ),
        (
            {
                "time_utc": ["2025-03-01T12:00:01Z", "2025-03-01T13:00:00.5+01:00"],
                "sequence_start": "2025-03-01T12:00:00Z",
            },
            r"time_utc\[1\] = '2025-03-01T13:00:00.5\+01:00': out of order: sort the samples",
        ),
        (
            {"time_utc": ["2025-03-01T12:00:00Z", "2025-03-01T12:00:01Z"], "sequence_start": 5.0},
            r"sequence_start = 5\.0 is seconds but the stamps are ISO-8601",
        ),
        (
            {"time_s": [0.0, 0.1], "sequence_start": "2025-03-01T12:00:00Z"},
            r"sequence_start = '2025-03-01T12:00:00Z' is an ISO-8601 time but the stamps "
            r"are seconds",
        ),
        (
            {"time_s": [0.0, 0.1], "sequence_start": "soon"},
            r"sequence_start = 'soon' is not an ISO-8601",
        ),
        (
            {"time_s": [0.0, "2025-03-01T12:00:01Z"]},
            r"time_s\[0\] = 0\.0 is a number but time_s\[1\] is a string",
        ),
        (
            {"time_s": [0.0, 0.1], "time_utc": ["2025-03-01T12:00:00Z"] * 2},
            r"as time_s or as time_utc, not both",
        ),
        ({}, r"needs time stamps: time_s \(seconds\) or time_utc"),
    ],
)
def test_bad_time_base_is_refused_naming_the_value(data: dict[str, Any], match: str) -> None:
    with pytest.raises(pydantic.ValidationError, match=match):
        Telemetry.model_validate({"omega_rad_s": [[0.0, 0.0, 0.0]] * 2, **data})


LEAP = ["2016-12-31T23:59:59.5Z", "2016-12-31T23:59:60Z", "2016-12-31T23:59:60.5Z"]


def test_a_leap_second_is_refused_as_one_not_as_no_iso_stamp() -> None:
    """23:59:60 is ISO 8601 (RFC 3339 writes it); a datetime cannot hold it. The refusal
    said the stamp "is not an ISO-8601 UTC time stamp", and a CSV's that it "is neither
    seconds nor an ISO-8601 UTC stamp", or, first in a CSV, that it named no column; now it
    says it is a leap second and which clock to give instead."""
    said = r"time_utc\[1\] = '2016-12-31T23:59:60Z' is a leap second \(second 60\).*GPS, TAI"
    with pytest.raises(pydantic.ValidationError, match=said):
        Telemetry(time_utc=LEAP, omega_rad_s=[[0.0, 0.0, 0.0]] * 3, sequence_start=LEAP[0])
    with pytest.raises(
        InputError, match=r"sequence_start = '2016-12-31t23:59:60\.25\+00:00' is a leap"
    ):
        parse_sequence_start("2016-12-31t23:59:60.25+00:00")
    with pytest.raises(pydantic.ValidationError, match=r"'2016-12-31T23:59:60Z' is a leap second"):
        parse_telemetry("\n".join(f"{s},0,0,0" for s in LEAP), sequence_start=LEAP[0])
    # First in a CSV, it was read as a header naming no column.
    with pytest.raises(pydantic.ValidationError, match=r"'2016-12-31T23:59:60Z' is a leap second"):
        parse_telemetry("\n".join(f"{s},0,0,0" for s in LEAP[1:]), sequence_start=LEAP[0])
    # On an ordinal date (the day of the year, read since the ordinal dates were) too.
    with pytest.raises(InputError, match=r"'2016-366T23:59:60Z' is a leap second"):
        parse_sequence_start("2016-366T23:59:60Z")
    # Second 61 is no time at all: refused as before.
    with pytest.raises(InputError, match=r"'2016-12-31T23:59:61Z' is not an ISO-8601"):
        parse_sequence_start("2016-12-31T23:59:61Z")


def test_telemetry_from_ten_seconds_before_the_sequence(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    """Quiescent samples before the start are kept for the caller, not classified."""
    result = simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(23))
    rng = np.random.default_rng(24)
    before = np.arange(-200, 1) / 20  # -10 s ... 0 s at 20 Hz

    def make(t: np.ndarray, w: np.ndarray) -> Telemetry:
        quiet = 1e-3 * rng.standard_normal((len(before), 3))
        stamps = np.concatenate([before, t, t[-1] + np.arange(1, 41) / 20]) + MISSION_START_S
        omega = np.concatenate([quiet, w, np.repeat(w[-1:], 40, axis=0)])  # a 2 s tail
        return plain(stamps, omega, sequence_start=MISSION_START_S)

    assert_all_identified(euclidean_classifier, make, result)
    t_before, w_before = make(result.time_s, result.omega_measured[0, 0]).before_start()
    assert len(t_before) == len(w_before) == 200
    assert t_before[0] == pytest.approx(-10.0) and t_before[-1] < 0.0
    # Stamps from the start, negative before it, need no sequence_start either.
    series = plain(np.concatenate([before, result.time_s]), np.zeros((201 + 80, 3)))
    assert len(series.before_start()[0]) == 200


# Rates, irregular stamps, drops and gaps.


@pytest.mark.parametrize("hz", [1.0, 10.0, 50.0, 200.0])
def test_any_rate_is_identified(
    euclidean_classifier: InertiaClassifier, paper: Scenario, hz: float
) -> None:
    result = simulate(at_rate(paper, hz), GOOD_SEQUENCE, 2, np.random.default_rng(int(hz)))
    assert result.time_s[0] == pytest.approx(1.0 / hz)  # the first sample one period in
    if hz >= 10:
        assert_all_identified(euclidean_classifier, plain, result, n=2)
        return
    # At 1 Hz (4 samples for a 4 s sequence) the interpolated series lies farther from its
    # candidate than the 20 Hz training noise went, and this kind compares series with each
    # axis' mean removed (the drift), which costs a 4-sample series much of its signal: the
    # verdict may be "ambiguous" or "matches none", but a candidate it names is the right one.
    verdicts = [
        identify(euclidean_classifier, plain(result.time_s, result.omega_measured[k, i]))
        for k in range(5)
        for i in range(2)
    ]
    truth = [k for k in range(5) for _ in range(2)]
    named = [
        (v.candidate_index, k)
        for v, k in zip(verdicts, truth, strict=True)
        if v.status == "identified"
    ]
    assert all(found == k for found, k in named), named
    assert len(named) >= 5
    assert sum(v.matches_none for v in verdicts) <= 1


def _random_thirty_percent(rng: np.random.Generator, count: int) -> np.ndarray:
    """A random ~30 % of the samples, the first and last kept: at 200 Hz, spacings of 5 ms
    to tens of ms, never regular."""
    keep = rng.random(count) < 0.3
    keep[[0, -1]] = True
    return keep


def _ten_percent_dropped_with_the_last(rng: np.random.Generator, count: int) -> np.ndarray:
    keep = np.ones(count, dtype=bool)
    keep[rng.choice(count - 1, size=count // 10 - 1, replace=False)] = False
    keep[-1] = False  # the last sample (at the end of the sequence) is lost too
    return keep


@pytest.mark.parametrize(
    ("hz", "n", "seed", "pick"),
    [
        pytest.param(200.0, 2, 25, _random_thirty_percent, id="irregular-stamps"),
        pytest.param(
            10.0, 3, 27, _ten_percent_dropped_with_the_last, id="ten-percent-dropped-at-10-hz"
        ),
    ],
)
def test_irregular_or_dropped_samples_are_identified(
    euclidean_classifier: InertiaClassifier,
    paper: Scenario,
    hz: float,
    n: int,
    seed: int,
    pick: Callable[[np.random.Generator, int], np.ndarray],
) -> None:
    """``pick`` chooses the samples kept, from the generator seeded ``seed + 1``."""
    result = simulate(at_rate(paper, hz), GOOD_SEQUENCE, n, np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)

    def make(t: np.ndarray, w: np.ndarray) -> Telemetry:
        keep = pick(rng, len(t))
        return plain(t[keep], w[keep])

    assert_all_identified(euclidean_classifier, make, result, n=n)


def test_a_gap_too_large_is_refused_naming_it(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    result = simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(29))
    t, w = result.time_s, result.omega_measured[0, 0]
    keep = (t < 1.5) | (t > 2.25)  # samples 1.5 s ... 2.25 s lost: no sample from 1.45 to 2.3
    with pytest.raises(
        ValueError,
        match=r"too thin for a verdict: no sample from 1\.45 s \(clock 810000124\.45 s\) to "
        r"2\.3 s \(clock 810000125\.3 s\) \(times from the sequence start\), a gap of "
        r"0\.85 s between samples; at most 0\.2 s is allowed \(4 x the period 0\.05 s\)",
    ):
        identify(
            euclidean_classifier,
            plain(t[keep] + MISSION_START_S, w[keep], sequence_start=MISSION_START_S),
        )
    # A gap of 4 periods is used as it is.
    keep = (t < 1.5) | (t > 1.6)
    assert identify(euclidean_classifier, plain(t[keep], w[keep])).candidate_index == 0


def test_first_sample_one_period_after_the_start_is_accepted() -> None:
    """1.5 periods after the start at most; the ends are extrapolated linearly."""
    grid = np.arange(1, 81) / 20
    slope = np.array([0.01, -0.02, 0.005])
    for first, ok in ((0.1, True), (0.15, True), (0.16, False)):
        t = np.arange(first, 4.0 + 1e-9, 0.1)  # 10 Hz
        telemetry = plain(t, t[:, None] * slope)
        if ok:
            np.testing.assert_allclose(resample(telemetry, grid), grid[:, None] * slope, atol=1e-12)
        else:
            with pytest.raises(ValueError, match=r"no sample from 0 s to 0\.16 s"):
                resample(telemetry, grid)


def test_a_dropout_outside_the_sequence_is_no_gap_in_it() -> None:
    """A dropout from before the start (or past the end) into the sequence counts only
    inside it: the telemetry resamples as it does with no samples out there at all
    (a reviewer's 10 Hz pass lost -5 s to 0.1 s and was refused, while the same file
    with every pre-start sample removed was identified)."""
    grid = np.arange(1, 81) / 20
    slope = np.array([0.01, -0.02, 0.005])
    inside = np.arange(0.1, 4.0 + 1e-9, 0.1)  # 10 Hz over the sequence
    for before, after in (
        (np.arange(-10.0, -5.0 + 1e-9, 0.1), np.array([])),  # lost -5 s ... 0.1 s
        (np.array([-0.5]), np.array([])),
        (np.array([]), np.array([8.0, 9.9])),  # lost 4 s ... 8 s
        (np.arange(-10.0, -1.0, 0.1), np.arange(6.0, 9.0, 0.1)),
    ):
        t = np.concatenate([before, inside, after])
        np.testing.assert_allclose(
            resample(plain(t, t[:, None] * slope), grid), grid[:, None] * slope, atol=1e-12
        )
    # The part within the sequence still has the edge's limit, 1.5 periods.
    t = np.concatenate([[-3.0], np.arange(0.2, 4.0 + 1e-9, 0.1)])
    with pytest.raises(ValueError, match=r"no sample from 0 s to 0\.2 s .* at an end of"):
        resample(plain(t, t[:, None] * slope), grid)


# Averaging.


def test_averaging_beats_picking_at_200_hz(quiet_paper: Scenario) -> None:
    """White gyro noise σ at 200 Hz on a 20 Hz grid: the cell averages have σ/√10."""
    result = simulate(at_rate(quiet_paper, 200.0), GOOD_SEQUENCE, 1, np.random.default_rng(0))
    truth = result.omega_measured[0, 0]
    grid = quiet_paper.sample_times(len(GOOD_SEQUENCE))
    sigma = 1e-3
    clean = resample(plain(result.time_s, truth), grid)
    np.testing.assert_allclose(clean, truth[9::10], atol=2e-4)  # the signal is not smeared
    rng = np.random.default_rng(1)
    averaged, picked = [], []
    for _ in range(20):
        noisy = truth + sigma * rng.standard_normal(truth.shape)
        averaged.append(resample(plain(result.time_s, noisy), grid) - clean)
        picked.append(noisy[9::10] - truth[9::10])
    noise_averaged, noise_picked = np.std(averaged), np.std(picked)
    assert noise_picked == pytest.approx(sigma, rel=0.1)
    assert noise_averaged == pytest.approx(sigma / np.sqrt(10), rel=0.15)


FIRE_BRAKE = [[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2


def _one_hz_two_second_steps(paper: Scenario, lowpass_s: float, hz: float) -> Scenario:
    """The paper's spacecraft with 2 s steps, noise off but the low-pass, sampled at hz."""
    data = paper.with_uncertainty(**{**NOISE_OFF, "lowpass_time_constant_s": lowpass_s})
    data = data.model_dump()
    data["timing"] = {"step_duration_s": 2.0, "integration_step_s": 0.01, "sample_rate_hz": hz}
    return Scenario.model_validate(data)


def test_response_shape_breaks_where_the_torque_may_change(paper: Scenario) -> None:
    # Steps 2 and 3 fire: the torque may change as they start, between them (each step's
    # jitter is its own) and as they end; the coasting steps around them break nothing.
    sequence = [[0] * 6, [4, 4, 4, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0] * 6, [0] * 6]
    shape = ResponseShape.of(_one_hz_two_second_steps(paper, 0.1, 1.0), sequence)
    assert (shape.boundaries_s, shape.lowpass_s) == ((2.0, 4.0, 6.0), 0.1)
    # Each break's largest change of acceleration, over candidates and axes: +2 N m on
    # y at the start (the lightest y, 52.1 kg m^2), the same at the handover, 0.5 N m on x
    # (one quarter-duty thruster, the lightest x 85.6 kg m^2) at the stop.
    smallest = paper.inertia_array.min(axis=0).diagonal()
    expected = (2 / smallest[1], 2 / smallest[1], 0.5 / smallest[0])
    assert shape.jumps_rad_s2 == pytest.approx(expected)
    assert shape.noise_rad_s == 0.0  # this scenario's gyro is noise-free
    assert ResponseShape.of(paper, [[0] * 6] * 3).boundaries_s == ()


@pytest.mark.parametrize("lowpass_s", [0.0, 0.1])
def test_a_cell_the_thrusters_switch_in_is_fitted_through_the_switch(
    paper: Scenario, lowpass_s: float
) -> None:
    """10 Hz telemetry on a 1 Hz grid, the thrusters reversing at 4 s: each grid time
    took the mean of its cell, off the rate at the reversal by about an eighth of a
    second's change of angular acceleration (4.9 mrad/s with the paper's low-pass, 7.4
    without: 5 to 7 gyro sigmas). Fitted through the break with its low-pass ramp, the
    value is the rate's there; elsewhere the cell is a mean as before (off by the
    gyroscopic term's curvature only, under 0.1 mrad/s); and with white noise it is
    still less noisy than one sample."""
    slow = _one_hz_two_second_steps(paper, lowpass_s, 1.0)
    fast = _one_hz_two_second_steps(paper, lowpass_s, 10.0)
    grid = slow.sample_times(len(FIRE_BRAKE))
    truth = simulate(slow, FIRE_BRAKE, 1, np.random.default_rng(0)).omega_true[0, 0]
    flown = simulate(fast, FIRE_BRAKE, 1, np.random.default_rng(0))
    omega = flown.omega_true[0, 0]
    shape = ResponseShape.of(slow, FIRE_BRAKE)
    means = resample(plain(flown.time_s, omega), grid)
    fitted = resample(plain(flown.time_s, omega), grid, shape=shape)
    reversal = int(np.flatnonzero(np.isclose(grid, 4.0))[0])
    assert np.abs(means - truth)[reversal].max() > 4e-3
    assert np.abs(fitted - truth)[reversal].max() < 1e-5
    assert np.abs(fitted - truth).max() < 1.5e-4
    sigma = 1e-3
    rng = np.random.default_rng(1)
    errors = []
    for _ in range(40):
        noisy = plain(flown.time_s, omega + sigma * rng.standard_normal(omega.shape))
        errors.append(resample(noisy, grid, shape=shape)[reversal] - truth[reversal])
    assert abs(float(np.mean(errors))) < 0.15 * sigma
    assert float(np.std(errors)) < 0.8 * sigma


def test_a_cell_holding_samples_after_its_switch_only_is_not_extrapolated_to_it(
    paper: Scenario,
) -> None:
    """10 Hz telemetry that drops out from 3.45 s to 4.05 s, across the thrusters'
    reversal at 4 s: that grid time's cell holds the samples at 4.1-4.4 s only. Fitted
    with a line plus the break's ramp and valued at 4 s, the fit ran back through the
    ramp's bend to the break: 5.7 gyro sigmas of noise in a value the likelihood judged
    as measured (genuine passes so cut on a 1 Hz model were called matches-none, 17 of
    20). The grid time is read about as well as one sample, or left out."""
    slow = _one_hz_two_second_steps(paper, 0.1, 1.0)
    fast = _one_hz_two_second_steps(paper, 0.1, 10.0)
    grid = slow.sample_times(len(FIRE_BRAKE))
    truth = simulate(slow, FIRE_BRAKE, 1, np.random.default_rng(0)).omega_true[0, 0]
    flown = simulate(fast, FIRE_BRAKE, 1, np.random.default_rng(0))
    kept = (flown.time_s < 3.45) | (flown.time_s > 4.05)
    t, omega = flown.time_s[kept], flown.omega_true[0, 0][kept]
    sigma = 1e-3
    shape = dataclasses.replace(ResponseShape.of(slow, FIRE_BRAKE), noise_rad_s=sigma)
    reversal = int(np.flatnonzero(np.isclose(grid, 4.0))[0])
    rng = np.random.default_rng(3)
    judged = []
    for _ in range(40):
        noisy = plain(t, omega + sigma * rng.standard_normal(omega.shape))
        resampled = resample_covered(noisy, grid, shape=shape)
        if resampled.observed[reversal]:
            judged.append(resampled.series[reversal] - truth[reversal])
    if judged:
        assert float(np.sqrt(np.mean(np.square(judged)))) < 1.5 * sigma


def test_a_boundary_between_identical_steps_is_averaged_not_fitted(paper: Scenario) -> None:
    """The shipped sequence fires the same thrusters four steps running: at 1, 2 and 3 s
    the commanded torque does not change (its jump is 0, only the jitter differs). A
    200 Hz gyro on the paper's 20 Hz grid had the cells there fitted through a break
    that bends nothing: their noise rose from the mean's 0.30 to 0.43-0.49 gyro sigma,
    for no bias removed. They are averaged, as between breaks."""
    sequence = [[4, 4, 4, 0, 0, 0]] * 4
    data = paper.with_uncertainty(**{**NOISE_OFF, "lowpass_time_constant_s": 0.1}).model_dump()
    data["timing"] = {"step_duration_s": 1.0, "integration_step_s": 0.005, "sample_rate_hz": 200.0}
    fast = Scenario.model_validate(data)
    grid = paper.sample_times(len(sequence))
    flown = simulate(fast, sequence, 1, np.random.default_rng(0))
    omega = flown.omega_true[0, 0]
    shape = ResponseShape.of(paper, sequence)
    assert shape.jumps_rad_s2[1:4] == (0.0, 0.0, 0.0)
    after = (grid > 0.99) & (grid < 1.2)
    sigma = 1e-3
    rng = np.random.default_rng(4)
    errors = []
    for _ in range(100):
        noisy = plain(flown.time_s, omega + sigma * rng.standard_normal(omega.shape))
        errors.append(resample(noisy, grid, shape=shape)[after] - resample(noisy, grid)[after])
    # Fitted or averaged, the same samples: the difference is the fit's extra noise.
    assert float(np.sqrt(np.mean(np.square(errors)))) < 0.1 * sigma


def test_on_the_presets_grid_no_cell_is_fitted(paper: Scenario) -> None:
    # 200 Hz on the paper's 20 Hz grid: a cell mean is off by 0.04 gyro sigma at a
    # reversal (the 0.1 s low-pass rounds it), less than the fit's noise would cost
    # (FIT_WORTH); the fit at the start had put a 200 Hz pass's decisions 0.02 s later.
    flown = simulate(at_rate(paper, 200.0), FIRE_BRAKE, 1, np.random.default_rng(3))
    telemetry = plain(flown.time_s, flown.omega_measured[0, 0])
    grid = paper.sample_times(len(FIRE_BRAKE))
    shape = ResponseShape.of(paper, FIRE_BRAKE)
    np.testing.assert_array_equal(resample(telemetry, grid, shape=shape), resample(telemetry, grid))


def test_the_shape_changes_nothing_for_telemetry_no_faster_than_the_grid(
    paper: Scenario,
) -> None:
    # One sample a cell: nothing to fit, the samples are read as before.
    slow = _one_hz_two_second_steps(paper, 0.1, 1.0)
    flown = simulate(slow, FIRE_BRAKE, 1, np.random.default_rng(2))
    telemetry = plain(flown.time_s, flown.omega_measured[0, 0])
    grid = slow.sample_times(len(FIRE_BRAKE))
    shape = ResponseShape.of(slow, FIRE_BRAKE)
    np.testing.assert_array_equal(resample(telemetry, grid, shape=shape), resample(telemetry, grid))


def test_one_kilohertz_at_mission_time_keeps_its_resolution() -> None:
    t = np.arange(1, 4001) / 1000
    omega = np.column_stack([np.sin(t), np.cos(t), t])
    telemetry = plain(t + MISSION_START_S, omega, sequence_start=MISSION_START_S)
    np.testing.assert_allclose(telemetry.time_array, t, atol=2e-7)
    grid = np.arange(1, 81) / 20
    expected = np.column_stack([np.sin(grid), np.cos(grid), grid])
    # Averaging over 50 ms smooths a curved signal by Δ² ω''/24 (here 1e-4 rad/s).
    np.testing.assert_allclose(resample(telemetry, grid), expected, atol=3e-4)


def test_mission_clock_offsets_are_exact_to_the_stamps_decimals() -> None:
    """A 10 Hz gyro on a mission clock, 10 s before the start: the stamps' 0.1 s steps are
    subtracted as decimals (the span read -9.899999976158142 and 0.004999995231628418 at
    200 Hz in the CLI's, the API's and the CSV's verdicts)."""
    rows = [f"{810_000_000 + k / 10:.1f},0,0,0" for k in range(-99, 41)]
    telemetry = parse_telemetry("time_s,wx,wy,wz\n" + "\n".join(rows), sequence_start=810_000_000)
    assert rows[0].startswith("809999990.1,")
    assert telemetry.inputs()["telemetry_span_s"] == [-9.9, 4.0]
    assert telemetry.time_array[:3].tolist() == [-9.9, -9.8, -9.7]
    fast = plain(
        [810_000_000.005, 810_000_000.01, 810_000_004.0],
        [[0, 0, 0]] * 3,
        sequence_start=810_000_000,
    )
    assert fast.inputs()["telemetry_span_s"] == [0.005, 4.0]
    # An averaging gyro is read at the midpoints, half a period (0.05 s) earlier: exact too.
    averaged = parse_telemetry(
        "time_s,wx,wy,wz\n" + "\n".join(rows), sequence_start=810_000_000, averaged=True
    )
    assert averaged.inputs()["telemetry_span_s"] == [-9.95, 3.95]
    # ISO stamps: whole microseconds divided once (0.05 s read 0.049999999999999996).
    utc = Telemetry(
        time_utc=["2025-03-01T12:00:00.05Z", "2025-03-01T12:00:04Z"],
        omega_rad_s=[[0, 0, 0]] * 2,
        sequence_start="2025-03-01T12:00:00Z",
    )
    assert utc.inputs()["telemetry_span_s"] == [0.05, 4.0]
    # A start with more decimals than the stamps: the offsets carry the start's.
    shifted = plain([810_000_000.1, 810_000_004.0], [[0, 0, 0]] * 2, sequence_start=810_000_000.25)
    assert shifted.inputs()["telemetry_span_s"] == [-0.15, 3.75]


# Estimating the start.


def test_estimate_sequence_start_finds_a_shifted_start(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    result = simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(30))
    grid = paper.sample_times(len(GOOD_SEQUENCE))
    score = lambda series: float(euclidean_classifier.transform(series[None])[0].min())  # noqa: E731
    pre = np.arange(-40, 1) / 20
    for k in range(5):
        # The sequence really started 0.3 s after the nominal start the operator gave.
        t = np.concatenate([pre, result.time_s]) + 0.3
        w = np.concatenate([np.zeros((41, 3)), result.omega_measured[k, 0]])
        telemetry = plain(t, w)
        shift, series = estimate_sequence_start(telemetry, grid, score, window_s=0.5)
        assert shift == pytest.approx(0.3, abs=0.05)
        assert int(np.argmin(euclidean_classifier.transform(series[None])[0])) == k
    with pytest.raises(ValueError, match=r"no start within ±0\.5 s fits the telemetry: .*too thin"):
        estimate_sequence_start(plain([0.0, 0.1], [[0, 0, 0]] * 2), grid, score, window_s=0.5)
    # A window beyond any use is refused before any work (1e9 s asked 298 GiB).
    with pytest.raises(ValueError, match=r"start window ±1e\+09 s at a 0\.05 s step is 4e\+10 "):
        estimate_sequence_start(telemetry, grid, score, window_s=1e9)
    assert estimate_sequence_start(telemetry, grid, score, window_s=100.0)[0] == pytest.approx(
        0.3, abs=0.05
    )


def test_a_csv_header_is_read_by_name() -> None:
    """Columns in the header's order, rates in the header's unit; a name that is no time
    or axis is refused by name. (The header used to be dropped and the columns read by
    position: ``time_s,wz,wy,wx`` put z where x belonged, and a confident verdict
    followed.)"""
    rows = [(0.05, 0.01, 0.02, 0.03), (0.10, 0.04, 0.05, 0.06)]

    def parsed(header: str, order: tuple[int, ...] = (0, 1, 2, 3), scale: float = 1.0) -> Any:
        lines = [header] + [
            ",".join(repr(row[j] / (scale if j else 1.0)) for j in order) for row in rows
        ]
        return parse_telemetry("\n".join(lines))

    expected = np.array([row[1:] for row in rows])
    for header, order in (
        ("time_s,wx,wy,wz", (0, 1, 2, 3)),
        ("time_s,wz,wy,wx", (0, 3, 2, 1)),
        ("wx_rad_s,wy_rad_s,wz_rad_s,time_s", (1, 2, 3, 0)),
        ("Time [s],gyro_x,gyro_y,gyro_z", (0, 1, 2, 3)),
        ("t,r,q,p", (0, 3, 2, 1)),
    ):
        telemetry = parsed(header, order)
        np.testing.assert_allclose(telemetry.omega_array, expected, err_msg=header)
        np.testing.assert_allclose(telemetry.time_array, [0.05, 0.10])
    degrees = parsed("time_s,wx_deg_s,wy_deg_s,wz_deg_s", scale=np.pi / 180)
    np.testing.assert_allclose(degrees.omega_array, expected)
    in_words = parsed("time (s),omega_x (deg/s),omega_y (deg/s),omega_z (deg/s)", scale=np.pi / 180)
    np.testing.assert_allclose(in_words.omega_array, expected)
    for header, match in (
        ("time_ms,wx,wy,wz", r"column 1 is 'time_ms': give the time stamps in seconds"),
        ("time_s,a,b,c", r"column 2 is 'a': not a time"),
        ("time_s,wx,wx,wz", r"names x twice"),
        ("time_s,wx_deg_s,wy,wz", r"mixes rad/s and deg/s"),
    ):
        with pytest.raises(InputError, match=match):
            parsed(header)
    # No header: time, x, y, z in rad/s, as before.
    np.testing.assert_allclose(
        parse_telemetry("0.05,0.01,0.02,0.03\n0.1,0.04,0.05,0.06").omega_array, expected
    )


def test_json_telemetry_states_deg_s_as_a_csv_header_does() -> None:
    """``omega_deg_s`` is JSON's ``wx_deg_s``: the same rates in deg/s read as the rad/s
    ones (the telemetry then holds omega_rad_s). Before, JSON had no way to say deg/s: the
    key was refused as unknown, and deg/s sent as omega_rad_s read 57 times too fast."""
    radians = [[0.01, 0.02, -0.03], [0.04, 0.05, 0.06]]
    degrees = np.degrees(radians).tolist()
    stamps = {"time_s": [0.05, 0.10]}
    in_degrees = parse_telemetry(json.dumps({**stamps, "omega_deg_s": degrees}))
    np.testing.assert_allclose(in_degrees.omega_array, radians, rtol=1e-15)
    assert in_degrees.omega_deg_s is None
    model = Telemetry.model_validate({**stamps, "omega_deg_s": degrees})
    np.testing.assert_allclose(model.omega_array, radians, rtol=1e-15)
    # A copy validated afresh keeps the rates (in rad/s) and the new start.
    moved = model.model_copy(update={"sequence_start": 0.05})
    np.testing.assert_allclose(moved.omega_array, radians, rtol=1e-15)
    np.testing.assert_allclose(moved.time_array, [0.0, 0.05])
    for document, match in (
        ({**stamps, "omega_rad_s": radians, "omega_deg_s": degrees}, r"not both"),
        (stamps, r"needs body rates: omega_rad_s \(rad/s\) or omega_deg_s \(deg/s\)"),
        ({**stamps, "omega_deg_s": [[1.0, 2.0, 3.0], [1.0, 2.0]]}, r"omega_deg_s row 1 has 2"),
        (
            {**stamps, "omega_deg_s": [[1.0, 2.0, 3.0], [1.0, 6000.0, 3.0]]},
            r"omega_deg_s\[1\]\[1\] = 6000.0 deg/s is beyond any attitude gyro's range",
        ),
    ):
        with pytest.raises(pydantic.ValidationError, match=match):
            parse_telemetry(json.dumps(document))
    # Strict numbers, as omega_rad_s: a string is no rate.
    with pytest.raises(pydantic.ValidationError, match="omega_deg_s"):
        Telemetry.model_validate({**stamps, "omega_deg_s": [["1", 2.0, 3.0], [1.0, 2.0, 3.0]]})
