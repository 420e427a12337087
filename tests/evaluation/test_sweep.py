"""Accuracy versus noise multiple, with Wilson intervals."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import (
    InertiaClassifier,
    Scenario,
    SweepResult,
    run_sweep,
    simulate,
    wilson_interval,
)
from inertia_id.evaluation.sweep import (
    MAX_MULTIPLE,
    NOISE_KINDS,
    check_ceiling_realisations,
    check_multiples,
)

Z = 1.959964


@pytest.fixture(scope="module")
def sweep(euclidean_classifier: InertiaClassifier) -> SweepResult:
    # 500 test series per point (100 per candidate): enough for disjoint intervals.
    return run_sweep(euclidean_classifier, multiples=(1, 8), n_test=500, seed=3)


# Wilson interval.


def test_wilson_known_values() -> None:
    # With no successes the lower bound is 0 and the upper z^2 / (n + z^2).
    low, high = wilson_interval(0, 10)
    assert low == pytest.approx(0.0, abs=1e-15)
    assert high == pytest.approx(Z**2 / (10 + Z**2), rel=1e-12)
    assert high == pytest.approx(0.2775, abs=1e-4)
    # All successes: lower bound n / (n + z^2), upper 1.
    low, high = wilson_interval(10, 10)
    assert low == pytest.approx(10 / (10 + Z**2), rel=1e-12)
    assert low == pytest.approx(0.7225, abs=1e-4)
    assert high == pytest.approx(1.0, abs=1e-15)
    for low, high in (wilson_interval(0, 10), wilson_interval(10, 10)):
        assert 0.0 <= low <= high <= 1.0
    low, high = wilson_interval(50, 100)
    assert low == pytest.approx(0.4038, abs=1e-4)
    assert high == pytest.approx(0.5962, abs=1e-4)
    assert wilson_interval(0, 0) == (0.0, 1.0)


@pytest.mark.parametrize("n", [1, 10, 40, 200, 500, 1000, 2000])
def test_wilson_ends_are_exactly_0_and_1_at_0_and_100_percent(n: int) -> None:
    # Computed, 200 of 200 gave an upper end of 0.9999999999999999 and 0 of 1000 a lower
    # end of 2e-19: a table would read "not quite certain" where the interval reaches 1.
    assert wilson_interval(n, n)[1] == 1.0
    assert wilson_interval(0, n)[0] == 0.0
    if n > 1:
        assert wilson_interval(n - 1, n)[1] < 1.0


@pytest.mark.parametrize(("k", "n"), [(1, 7), (3, 20), (17, 40), (99, 100), (480, 500)])
def test_wilson_properties(k: int, n: int) -> None:
    low, high = wilson_interval(k, n)
    assert 0.0 <= low < k / n < high <= 1.0
    # Symmetric under swapping successes and failures.
    mirror = wilson_interval(n - k, n)
    assert low == pytest.approx(1.0 - mirror[1], abs=1e-12)
    assert high == pytest.approx(1.0 - mirror[0], abs=1e-12)
    # Narrower with ten times the data at the same proportion.
    wide, narrow = high - low, np.subtract(*reversed(wilson_interval(10 * k, 10 * n)))
    assert narrow < wide
    # Wider for 99 % than for 95 %.
    low99, high99 = wilson_interval(k, n, z=2.575829)
    assert low99 < low and high99 > high


# The sweep.


def test_sweep_result_contents(sweep: SweepResult, paper: Scenario) -> None:
    assert sweep.candidate_names == paper.candidate_names
    assert sweep.sequence == GOOD_SEQUENCE
    assert sweep.metric == "euclidean"
    assert sweep.seed == 3
    assert sweep.n_test_per_candidate == 100
    assert [(p.noise, p.multiple) for p in sweep.points] == [
        ("process", 1.0),
        ("process", 8.0),
        ("measurement", 1.0),
        ("measurement", 8.0),
    ]
    assert [p.multiple for p in sweep.curve("process")] == [1.0, 8.0]
    assert [p.noise for p in sweep.curve("measurement")] == ["measurement"] * 2
    for point in sweep.points:
        confusion = np.asarray(point.confusion)
        assert point.n_series == 500 == confusion.sum()
        np.testing.assert_array_equal(confusion.sum(axis=1), 100)
        correct = int(np.trace(confusion))
        assert point.accuracy == pytest.approx(correct / 500, rel=1e-15)
        assert (point.ci_low, point.ci_high) == pytest.approx(wilson_interval(correct, 500))
        assert point.ci_low <= point.accuracy <= point.ci_high
        assert 0.0 <= point.f1 <= 1.0


def test_sweep_json_round_trip(sweep: SweepResult) -> None:
    text = sweep.model_dump_json()
    again = SweepResult.model_validate_json(text)
    assert again == sweep
    assert again.model_dump_json() == text


def test_more_noise_is_no_easier(sweep: SweepResult) -> None:
    process = {p.multiple: p for p in sweep.curve("process")}
    measurement = {p.multiple: p for p in sweep.curve("measurement")}
    assert process[1.0].accuracy >= process[8.0].accuracy
    assert measurement[1.0].accuracy >= measurement[8.0].accuracy
    # At 1x the good sequence separates everything; 8x the process noise really hurts:
    # the Wilson intervals do not even overlap.
    assert process[1.0].accuracy == 1.0
    assert process[1.0].ci_low > process[8.0].ci_high


def test_zero_noise_multiple_is_allowed(euclidean_classifier: InertiaClassifier) -> None:
    result = run_sweep(euclidean_classifier, multiples=[0.0], noises=["process"], n_test=25)
    assert len(result.points) == 1 and result.points[0].accuracy == 1.0


def test_a_points_level_is_written_without_binary_dust(
    euclidean_classifier: InertiaClassifier,
) -> None:
    """3 and 6 times the paper's 0.05 N m disturbance were written 0.15000000000000002 and
    0.30000000000000004 N m in the points table (a hostile review's sweep CSV)."""
    result = run_sweep(euclidean_classifier, multiples=[3, 6], noises=["process"], n_test=5)
    assert [point.value for point in result.points] == [0.15, 0.3]
    assert "0.15000000000000002" not in result.model_dump_json()


def test_progress_is_reported(euclidean_classifier: InertiaClassifier) -> None:
    fractions: list[float] = []
    run_sweep(euclidean_classifier, multiples=(1, 2), n_test=10, progress=fractions.append)
    assert fractions == pytest.approx([0.25, 0.5, 0.75, 1.0])


def test_should_stop_stops_early(euclidean_classifier: InertiaClassifier) -> None:
    polls: list[int] = []

    def stop_after_one_point() -> bool:
        polls.append(1)
        return len(polls) > 1

    fractions: list[float] = []
    result = run_sweep(
        euclidean_classifier,
        multiples=(1, 2, 3),
        n_test=10,
        should_stop=stop_after_one_point,
        progress=fractions.append,
    )
    assert len(result.points) == 1
    assert (result.points[0].noise, result.points[0].multiple) == ("process", 1.0)
    assert fractions == pytest.approx([1 / 6])
    assert len(polls) == 2
    nothing = run_sweep(euclidean_classifier, multiples=(1, 2), n_test=10, should_stop=lambda: True)
    assert nothing.points == []


def test_points_do_not_depend_on_what_else_is_swept(
    euclidean_classifier: InertiaClassifier,
) -> None:
    """Each point has its own stream: the first point is the same whatever follows."""
    a = run_sweep(euclidean_classifier, multiples=(8,), noises=["process"], n_test=50, seed=1)
    b = run_sweep(euclidean_classifier, multiples=(8, 2), noises=["process"], n_test=50, seed=1)
    assert a.points[0] == b.points[0]


def test_explicit_scenario_and_sequence(paper: Scenario) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 6, np.random.default_rng(0)).dataset()
    bare = InertiaClassifier("euclidean", random_state=0).fit(X, y)
    with pytest.raises(ValueError, match="does not carry its scenario and sequence; pass them"):
        run_sweep(bare, multiples=(1,), n_test=10)
    result = run_sweep(bare, scenario=paper, sequence=GOOD_SEQUENCE, multiples=(1,), n_test=10)
    assert len(result.points) == 2 and result.n_test_per_candidate == 2


@pytest.mark.parametrize(
    "multiples",
    [[-1.0], [1.0, math.nan], [math.inf], []],
)
def test_bad_multiples_are_rejected(
    euclidean_classifier: InertiaClassifier, multiples: list[float]
) -> None:
    shown = str(list(multiples)).replace("[", r"\[").replace("]", r"\]")
    with pytest.raises(ValueError, match=rf"multiples must be finite and >= 0, got {shown}"):
        run_sweep(euclidean_classifier, multiples=multiples, n_test=10)


@pytest.mark.parametrize("multiples", [[1.0, 1e6], [1e300], [1000.5]])
def test_multiples_beyond_the_largest_are_refused_naming_them(
    euclidean_classifier: InertiaClassifier, multiples: list[float]
) -> None:
    # 1e6x process noise made every series nan and failed naming a series, not the multiple.
    large = [m for m in multiples if m > MAX_MULTIPLE]
    with pytest.raises(ValueError, match=rf"at most 1000 \(.*\), got {re.escape(str(large))}"):
        run_sweep(euclidean_classifier, multiples=multiples, n_test=10)
    with pytest.raises(ValueError, match="at most 1000"):
        check_multiples(multiples)


def test_a_multiple_given_twice_is_refused_naming_it(
    euclidean_classifier: InertiaClassifier,
) -> None:
    """[1, 1] was swept as two points at 1x, offered as "x1" twice by the dashboard."""
    with pytest.raises(ValueError, match=r"each be given once, got \[1\.0\] more than once"):
        run_sweep(euclidean_classifier, multiples=[1, 2, 1.0], n_test=10)
    assert check_multiples([0, 1, 2]) == [0.0, 1.0, 2.0]


def test_every_source_at_the_largest_multiple_simulates_finite_rates(
    euclidean_classifier: InertiaClassifier,
) -> None:
    assert MAX_MULTIPLE == 1000
    result = run_sweep(
        euclidean_classifier, multiples=(MAX_MULTIPLE,), noises=NOISE_KINDS, n_test=10, seed=2
    )
    assert [p.noise for p in result.points] == list(NOISE_KINDS)
    assert all(0.0 <= p.accuracy <= 1.0 for p in result.points)


def test_a_scenario_that_overflows_below_the_bound_names_the_noise_and_multiple(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    # A disturbance of 1000 N m at 1x on bodies of 52 to 100 kg m^2: 1000x of it drives
    # the rates to inf.
    wild = paper.with_uncertainty(disturbance_torque_sigma_nm=1000.0)
    with pytest.raises(ValueError, match=r"process noise at multiple 1000 \(1e\+06 N m\)"):
        run_sweep(
            euclidean_classifier,
            scenario=wild,
            noises=["process"],
            multiples=(1, 1000),
            n_test=10,
        )


@pytest.mark.parametrize("bad", [1, 2, -1])
def test_the_ceilings_size_rule_is_the_cores(bad: int) -> None:
    with pytest.raises(ValueError, match=f"got {bad}"):
        check_ceiling_realisations(bad)
    assert check_ceiling_realisations(0) == 0 and check_ceiling_realisations(3) == 3


@pytest.mark.parametrize("noises", [["thermal"], ["process", "gyro"], []])
def test_bad_noises_are_rejected(
    euclidean_classifier: InertiaClassifier, noises: list[str]
) -> None:
    shown = str(list(noises)).replace("[", r"\[").replace("]", r"\]")
    with pytest.raises(
        ValueError,
        match=rf"noises must be among \['process', 'measurement', 'jitter', 'thrust_scale', "
        rf"'gyro_bias'\], "
        rf"got {shown}",
    ):
        run_sweep(euclidean_classifier, noises=noises, n_test=10)


def test_bad_sizes_and_sequences_are_rejected(euclidean_classifier: InertiaClassifier) -> None:
    with pytest.raises(ValueError, match="n_test = 3 is fewer than the 5 candidates"):
        run_sweep(euclidean_classifier, n_test=3)
    with pytest.raises(ValueError, match=r"level index 9 is outside 0\.\.4"):
        run_sweep(euclidean_classifier, sequence=[[9, 0, 0, 0, 0, 0]], n_test=10)


# More sources of error, other classifiers on the same series, bodies off the candidates.


def test_each_source_scales_its_own_level_and_a_zero_level_uses_the_reference(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    from inertia_id.evaluation.sweep import REFERENCE_LEVELS, noise_level

    assert paper.uncertainty.thrust_scale_sigma == 0.0
    assert noise_level(paper, "thrust_scale") == REFERENCE_LEVELS["thrust_scale"]
    assert noise_level(paper, "jitter") == paper.uncertainty.duty_jitter_sigma
    result = run_sweep(
        euclidean_classifier,
        noises=["jitter", "thrust_scale", "gyro_bias"],
        multiples=(0, 8),
        n_test=250,
        seed=4,
    )
    assert result.levels == {
        "jitter": 0.02,
        "thrust_scale": REFERENCE_LEVELS["thrust_scale"],
        "gyro_bias": REFERENCE_LEVELS["gyro_bias"],
    }
    assert result.units["gyro_bias"] == "rad/s"
    for noise in ("jitter", "thrust_scale"):
        clean, noisy = result.curve(noise)
        assert (clean.value, noisy.value) == (0.0, 8 * result.levels[noise])
        # Eight times the 1x level of either confounds the candidates (5-15 % apart):
        # accuracy falls by far more than its interval.
        assert noisy.ci_high < clean.ci_low, noise
    # A constant gyro bias is an offset per axis, which the Euclidean clustering removes
    # before comparing (BaseClassifier.REMOVES_OFFSET): eight times its reference level
    # costs it nothing beyond the interval.
    clean, noisy = result.curve("gyro_bias")
    assert (clean.value, noisy.value) == (0.0, 8 * result.levels["gyro_bias"])
    assert noisy.ci_high >= clean.ci_low


def test_thrust_scale_error_is_drawn_into_the_simulation(paper: Scenario) -> None:
    from inertia_id.evaluation.sweep import noise_level

    erred = paper.with_uncertainty(thrust_scale_sigma=4 * noise_level(paper, "thrust_scale"))
    clean = simulate(paper, GOOD_SEQUENCE, 30, np.random.default_rng(0))
    scaled = simulate(erred, GOOD_SEQUENCE, 30, np.random.default_rng(0))
    # The final rates spread more across realisations of the same candidate.
    assert (
        scaled.final_rate_rad_s.std(axis=1).mean() > 2 * clean.final_rate_rad_s.std(axis=1).mean()
    )


def test_other_classifiers_are_scored_on_the_same_series(
    euclidean_classifier: InertiaClassifier,
) -> None:
    result = run_sweep(
        euclidean_classifier,
        others={"copy": euclidean_classifier},
        multiples=(1, 6),
        n_test=100,
        seed=5,
    )
    assert list(result.others) == ["copy"]
    assert result.others["copy"] == result.points
    assert result.curve("process", "copy") == result.curve("process")


def test_a_body_off_the_candidates_is_flagged_and_a_candidate_is_not(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    from inertia_id.evaluation.sweep import run_inertia_sweep

    result = run_inertia_sweep(
        euclidean_classifier, scales=(1.0, 1.4), between=(0.0, 1.0), n_test=40, seed=6
    )
    scaled_1, scaled_14, end_a, end_b = result.points
    a, b = result.pair
    # The default pair is the closest two candidates.
    gaps = {
        (i, j): np.linalg.norm(
            np.subtract(
                paper.inertia_candidates[i].inertia_kg_m2, paper.inertia_candidates[j].inertia_kg_m2
            )
        )
        for i in range(5)
        for j in range(i + 1, 5)
    }
    assert min(gaps, key=gaps.get) == (a, b)  # type: ignore[arg-type]
    assert scaled_1.matches_none_rate <= 0.05 and scaled_1.predicted[0] == 40
    assert end_a.predicted[a] == 40 and end_b.predicted[b] == 40
    assert end_a.matches_none_rate <= 0.05 and end_b.matches_none_rate <= 0.05
    # 40 % heavier than every candidate: flagged.
    assert scaled_14.matches_none_rate == 1.0
    assert np.allclose(
        scaled_14.inertia_kg_m2, 1.4 * np.asarray(paper.inertia_candidates[0].inertia_kg_m2)
    )


def test_bodies_off_the_candidates_are_counted_as_identify_answers_them(paper: Scenario) -> None:
    """The sweep's table is identify's verdict on the same series: before, it counted
    only the series beyond the novelty threshold, and called the first candidate scaled
    by 0.8 "matches none" 0 times in 20 where identify says so every time (the
    posterior's "other bodies" model)."""
    from collections import Counter

    from inertia_id import Telemetry, identify, train_classifier
    from inertia_id.evaluation.identify import STATUSES
    from inertia_id.evaluation.sweep import body_series, run_inertia_sweep
    from inertia_id.physics.sequences import hand_designed

    model = train_classifier(paper, hand_designed(paper, 4), 20, np.random.default_rng(0))
    scales, n_test, seed = (0.6, 0.8, 1.0, 1.2), 20, 5
    result = run_inertia_sweep(model, scales=scales, between=(), n_test=n_test, seed=seed)
    grid = paper.sample_times(len(hand_designed(paper, 4))).tolist()
    streams = np.random.SeedSequence(seed).spawn(len(scales))
    for point, stream in zip(result.points, streams, strict=True):
        series = body_series(
            paper,
            model.sequence_,
            np.asarray(point.inertia_kg_m2),
            n_test,
            np.random.default_rng(stream),
        )
        answers = [identify(model, Telemetry(time_s=grid, omega_rad_s=x.tolist())) for x in series]
        assert point.matches_none_rate == np.mean([a.matches_none for a in answers])
        counted = Counter(a.status for a in answers)
        assert point.statuses == {status: counted[status] for status in STATUSES}
        assert (
            point.predicted
            == np.bincount(
                [a.candidate_index for a in answers], minlength=paper.n_candidates
            ).tolist()
        )
    shrunk_06, shrunk_08, itself, grown_12 = result.points
    assert shrunk_06.matches_none_rate == shrunk_08.matches_none_rate == 1.0
    assert grown_12.matches_none_rate == 1.0
    assert itself.true_candidate == 0 and shrunk_08.true_candidate is None
    assert itself.matches_none_rate == 0.0 and itself.identified_right_rate == 1.0
    assert result.required_confidence == 0.99


def test_an_inertia_sweep_stored_before_the_verdicts_still_reads(
    euclidean_classifier: InertiaClassifier,
) -> None:
    from inertia_id.evaluation.sweep import InertiaSweepResult, run_inertia_sweep

    stored = run_inertia_sweep(euclidean_classifier, scales=(1.4,), between=(), n_test=4)
    old = stored.model_dump()
    old.pop("required_confidence")
    for point in old["points"]:
        for field in ("true_candidate", "statuses", "identified", "identified_right_rate"):
            point.pop(field)
        point.pop("identified_wrong_rate")
        point.pop("ambiguous_rate")
    read = InertiaSweepResult.model_validate(old)
    assert read.required_confidence is None and read.points[0].statuses == {}
    assert read.points[0].matches_none_rate == stored.points[0].matches_none_rate


@pytest.mark.parametrize(
    ("options", "quoted"),
    [
        ({"scales": (0.0,)}, "scales must be finite and > 0, got [0.0]"),
        ({"between": (1.5,)}, "between positions must be in [0, 1], got [1.5]"),
        ({"pair": (0, 9)}, "pair[1] = 9 is not a candidate index 0..4"),
        ({"n_test": 0}, "n_test must be at least 1, got 0"),
    ],
)
def test_bad_inertia_sweep_options_are_named(
    euclidean_classifier: InertiaClassifier, options: dict, quoted: str
) -> None:
    from inertia_id.evaluation.sweep import run_inertia_sweep

    with pytest.raises(ValueError) as info:
        run_inertia_sweep(euclidean_classifier, **options)
    assert quoted in str(info.value)


def test_the_ceiling_is_fitted_at_each_noise_and_is_never_below_the_classifier(
    euclidean_classifier: InertiaClassifier,
) -> None:
    result = run_sweep(
        euclidean_classifier, multiples=(1, 6), n_test=500, ceiling_realisations=1000, seed=8
    )
    assert result.limit_realisations == 1000 == result.ceiling_realisations
    assert [(p.noise, p.multiple) for p in result.limit] == [
        (p.noise, p.multiple) for p in result.points
    ]
    for mine, limit in zip(result.points, result.limit, strict=True):
        p = mine.accuracy
        sampling_error = 2 * math.sqrt(2 * p * (1 - p) / mine.n_series) + 1 / mine.n_series
        assert limit.accuracy >= mine.accuracy - sampling_error, (mine, limit)
    # At 6x process noise a classifier trained at 1x is beaten by one that knows the noise.
    assert result.limit[1].accuracy > result.points[1].accuracy


def test_each_point_says_whether_it_lies_above_the_ceilings_interval(
    euclidean_classifier: InertiaClassifier,
) -> None:
    result = run_sweep(
        euclidean_classifier,
        others={"again": euclidean_classifier},
        multiples=(1, 8),
        n_test=50,
        ceiling_realisations=20,
        seed=4,
    )
    assert result.ceiling and all(c.above_ceiling_interval is None for c in result.ceiling)
    for line in (result.points, result.others["again"]):
        for point, ceiling in zip(line, result.ceiling, strict=True):
            assert (point.noise, point.multiple) == (ceiling.noise, ceiling.multiple)
            assert point.above_ceiling_interval is (point.accuracy > ceiling.ci_high)
    # At 1x the ceiling is 100 %: its interval reaches 1 and nothing lies above it.
    assert result.ceiling[0].accuracy == 1.0 and result.ceiling[0].ci_high == 1.0
    assert result.points[0].above_ceiling_interval is False
    without = run_sweep(euclidean_classifier, multiples=(1,), n_test=10)
    assert [p.above_ceiling_interval for p in without.points] == [None, None]


@pytest.mark.parametrize("bad", [2, -1, 1.5, True])
def test_a_bad_limit_size_is_quoted(euclidean_classifier: InertiaClassifier, bad: object) -> None:
    with pytest.raises(ValueError, match=f"got {bad!r}"):
        run_sweep(euclidean_classifier, multiples=(1,), n_test=10, limit_realisations=bad)  # type: ignore[arg-type]


def test_a_scenario_at_every_noise_bound_is_swept_at_the_largest_multiple() -> None:
    """The bounds are on what a scenario states; a sweep scales a sigma up to 1000x
    (MAX_MULTIPLE, the service's cap too) past them. Its jitter and thrust-scale copies
    were validated again, so a scenario at a bound was refused in the middle of its job
    (and one at 2x of a bound too). A body the size of the International Space Station
    (inertia 1e6 times the paper's), so that 1000x its disturbance bound of 1e6 N m still
    leaves finite rates; every other figure at its bound (the lag at 100 steps)."""
    from inertia_id import preset, train

    paper = preset("paper")
    generator = paper.candidate_generator
    assert generator is not None
    base = (1e6 * np.asarray(generator.base_inertia_kg_m2)).tolist()
    at_bounds = preset(
        "paper",
        inertia_candidates=[],
        candidate_generator={**generator.model_dump(), "base_inertia_kg_m2": base},
        thrusters={"nominal_torque_nm": 2e4, "n_levels": 5},
        uncertainty={
            **paper.uncertainty.model_dump(),
            # MAX_DUTY_JITTER_SIGMA, MAX_THRUST_SCALE_SIGMA, MAX_DISTURBANCE_TORQUE_SIGMA_NM,
            # MAX_LAG_STEPS steps of 1 s and MAX_RATE_SIGMA_RAD_S.
            "duty_jitter_sigma": 10.0,
            "thrust_scale_sigma": 0.5,
            "disturbance_torque_sigma_nm": 1e6,
            "lowpass_time_constant_s": 100.0,
            "gyro_bias_sigma_rad_s": 100.0,
        },
    )
    classifier = train(at_bounds, GOOD_SEQUENCE, 5, np.random.default_rng(0), metric="euclidean")
    result = run_sweep(
        classifier, multiples=(2, MAX_MULTIPLE), noises=NOISE_KINDS, n_test=10, seed=1
    )
    assert [(p.noise, p.multiple) for p in result.points] == [
        (noise, m) for noise in NOISE_KINDS for m in (2.0, MAX_MULTIPLE)
    ]
    assert all(0.0 <= p.accuracy <= 1.0 for p in result.points)
    values = {(p.noise, p.multiple): p.value for p in result.points}
    assert values["jitter", MAX_MULTIPLE] == 1e4 and values["thrust_scale", MAX_MULTIPLE] == 500
    assert values["process", MAX_MULTIPLE] == 1e9 and values["gyro_bias", MAX_MULTIPLE] == 1e5


def test_the_papers_jitter_and_thrust_scale_at_their_bounds_are_swept_at_1000x(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    """On the paper preset's own bodies, 1000x of the thrust-scale bound (0.5) still
    simulates (it overflows from about 700)."""
    at_bounds = paper.with_uncertainty(duty_jitter_sigma=10.0, thrust_scale_sigma=0.5)
    result = run_sweep(
        euclidean_classifier,
        scenario=at_bounds,
        multiples=(MAX_MULTIPLE,),
        noises=["jitter", "thrust_scale"],
        n_test=50,
        seed=4,
    )
    assert [p.value for p in result.points] == [1e4, 500.0]
