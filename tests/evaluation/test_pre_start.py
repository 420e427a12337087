"""Telemetry before the sequence start (GitHub issue 13): it measures the body's rate plus
the gyro bias at the start, and the default classifier conditions on that offset."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import Scenario, simulate
from inertia_id.classifiers.marginal import MarginalLikelihoodClassifier, train_marginal
from inertia_id.classifiers.registry import classifier_from_json
from inertia_id.errors import InputError
from inertia_id.evaluation.identify import identify, identify_online, initial_offset
from inertia_id.evaluation.telemetry import Telemetry
from inertia_id.physics.simulate import Simulator

#: Coast steps flown before the sequence: 10 s of telemetry before the start.
COAST = 10
#: Its 1 Hz samples strictly before the start (-9 s to -1 s; the one at 0 is the start).
BEFORE = COAST - 1


def _flown(scenario: Scenario, n: int, seed: int) -> Any:
    """n series per candidate that begin COAST steps (1 s each) before the sequence."""
    sequence = [[0] * scenario.n_thrusters] * COAST + GOOD_SEQUENCE
    return simulate(scenario, sequence, n, np.random.default_rng(seed))


def _telemetry(result: Any, k: int, r: int, every: int) -> Telemetry:
    """Series (k, r) every ``every``-th sample, stamps shifted so 0 is the start."""
    time_s = result.time_s - COAST * 1.0
    return Telemetry(
        time_s=time_s[every - 1 :: every].tolist(),
        omega_rad_s=result.omega_measured[k, r, every - 1 :: every].tolist(),
        sequence_start=0.0,
    )


@pytest.fixture(scope="module")
def marginal(drifting_paper: Scenario) -> MarginalLikelihoodClassifier:
    return train_marginal(drifting_paper, GOOD_SEQUENCE, 60, np.random.default_rng(31))


@pytest.fixture(scope="module")
def flown(drifting_paper: Scenario) -> Any:
    return _flown(drifting_paper, 8, 32)


def test_the_offset_error_matches_its_predicted_spread(drifting_paper: Scenario) -> None:
    # The closed form (gyro noise over n samples plus the disturbance's random walk since
    # each sample) against the measured error of the mean of the 1 Hz samples before the
    # start, ĉ - (ω(0) + b), over 600 series, with ω(0) the true rate at the start and b
    # the bias drawn (the simulator draws each realisation's constants first).
    n, seed = 120, 33
    result = _flown(drifting_paper, n, seed)
    bias = Simulator(drifting_paper, n).draw_initial(np.random.default_rng(seed)).gyro_bias
    start = int(np.flatnonzero(np.isclose(result.time_s, COAST * 1.0))[0])
    errors, predicted = [], np.zeros(3)
    for k in range(drifting_paper.n_candidates):
        for r in range(n):
            offset = initial_offset(drifting_paper, _telemetry(result, k, r, 20))
            assert offset is not None and offset.samples == BEFORE
            truth = result.omega_true[k, r, start] + bias[k, r]
            errors.append(np.asarray(offset.offset_rad_s) - truth)
            predicted = np.asarray(offset.std_rad_s)
    np.testing.assert_allclose(np.std(np.asarray(errors), axis=0), predicted, rtol=0.15)
    # Ten times tighter than the prior it replaces (5e-3 and 2e-3 rad/s in orbit).
    assert np.all(predicted < 0.1 * np.hypot(5e-3, 2e-3))


def test_no_samples_before_the_start_means_no_offset(drifting_paper: Scenario, flown: Any) -> None:
    telemetry = _telemetry(flown, 0, 0, 20)
    assert initial_offset(drifting_paper, telemetry, 0.0) is None
    late = Telemetry(
        time_s=[t for t in telemetry.time_s if t > 0],
        omega_rad_s=[
            w for t, w in zip(telemetry.time_s, telemetry.omega_rad_s, strict=True) if t > 0
        ],
        sequence_start=0.0,
    )
    assert initial_offset(drifting_paper, late) is None


@pytest.mark.parametrize("window", [-1.0, float("nan"), "10", True])
def test_a_bad_window_is_refused_naming_it(
    marginal: MarginalLikelihoodClassifier, flown: Any, window: Any
) -> None:
    with pytest.raises(InputError, match="pre_start_window_s") as caught:
        identify(marginal, _telemetry(flown, 0, 0, 2), pre_start_window_s=window)
    assert repr(window) in str(caught.value)


def test_one_hertz_telemetry_gains_from_the_part_before_the_start(
    marginal: MarginalLikelihoodClassifier, flown: Any
) -> None:
    # 1 Hz: four samples in the 4 s sequence. Without the part before the start the
    # offset (5.4e-3 rad/s a priori) eats three of twelve numbers; with it the verdict
    # is surer on every candidate, and never wrong.
    gains = []
    for k in range(marginal.n_candidates_):
        for r in range(8):
            telemetry = _telemetry(flown, k, r, 20)
            with_part = identify(marginal, telemetry)
            without = identify(marginal, telemetry, pre_start_window_s=0.0)
            assert with_part.candidate_index == k
            assert with_part.pre_start_samples == BEFORE and without.pre_start_samples == 0
            assert without.initial_offset_rad_s is None
            assert without.initial_offset_deg_s is None
            np.testing.assert_allclose(
                with_part.initial_offset_deg_s,
                np.asarray(with_part.initial_offset_rad_s) * 180 / np.pi,
                rtol=1e-12,
            )
            np.testing.assert_allclose(
                with_part.initial_offset_std_deg_s,
                np.asarray(with_part.initial_offset_std_rad_s) * 180 / np.pi,
                rtol=1e-12,
            )
            assert with_part.posterior[with_part.candidate] >= 0.5
            gains.append(np.log(with_part.confidence / max(without.confidence, 1e-300)))
    assert np.mean(np.asarray(gains) > 0) >= 0.8
    assert np.median(gains) > 0


def test_the_online_decision_comes_sooner_with_the_part_before_the_start(
    marginal: MarginalLikelihoodClassifier, flown: Any
) -> None:
    decided = {True: 0, False: 0}
    for k in range(marginal.n_candidates_):
        for r in range(8):
            telemetry = _telemetry(flown, k, r, 2)
            for use in (True, False):
                online = identify_online(
                    marginal, telemetry, pre_start_window_s=10.0 if use else 0.0
                )
                if online.decided:
                    assert online.candidate_index == k
                    decided[use] += 1
    assert decided[True] >= decided[False]


def test_the_offset_free_parts_survive_storage(
    marginal: MarginalLikelihoodClassifier, flown: Any
) -> None:
    assert marginal.supports_offset
    reloaded = classifier_from_json(marginal.to_json())
    assert reloaded.supports_offset
    telemetry = _telemetry(flown, 2, 1, 20)
    a, b = identify(marginal, telemetry), identify(reloaded, telemetry)
    assert a.initial_offset_rad_s == b.initial_offset_rad_s
    np.testing.assert_allclose(list(a.posterior.values()), list(b.posterior.values()), atol=1e-9)


def test_a_classifier_without_offset_free_parts_ignores_the_part_before_the_start(
    marginal: MarginalLikelihoodClassifier, flown: Any
) -> None:
    data = marginal.to_dict()
    data.pop("offset_free")
    older = MarginalLikelihoodClassifier.from_dict(data)
    assert not older.supports_offset
    telemetry = _telemetry(flown, 3, 0, 20)
    verdict = identify(older, telemetry)
    assert verdict.initial_offset_rad_s is None and verdict.pre_start_samples == 0
    assert verdict.posterior == identify(older, telemetry, pre_start_window_s=0.0).posterior
    with pytest.raises(InputError, match="retrain"):
        older.conditioned_on_offset(np.zeros((3, 3)), np.zeros((3, 3)))


@pytest.mark.parametrize(("process", "measurement"), [(1.0, 1.0), (1.0, 4.0), (8.0, 1.0)])
def test_the_samples_before_the_start_say_how_noisy_the_spacecraft_is(
    drifting_paper: Scenario,
    marginal: MarginalLikelihoodClassifier,
    process: float,
    measurement: float,
) -> None:
    # Their scatter about their mean is gyro noise plus the disturbance's random walk:
    # the noise conditions' posterior given 10 s at 10 Hz sits at the true multiples
    # (octaves for the process noise, thirds of an octave for the gyro).
    sequence = [[0] * drifting_paper.n_thrusters] * COAST + GOOD_SEQUENCE
    result = simulate(
        drifting_paper,
        sequence,
        4,
        np.random.default_rng(34),
        process_noise_scale=process,
        measurement_noise_scale=measurement,
    )
    grid = marginal.grid_
    for k in range(drifting_paper.n_candidates):
        for r in range(4):
            offset = initial_offset(drifting_paper, _telemetry(result, k, r, 2))
            assert offset is not None
            weights = np.exp(offset.condition_log_weights(grid))
            assert weights.sum() == pytest.approx(1.0)
            log_multiples = np.log2(grid)
            mean_log = weights @ log_multiples
            assert abs(mean_log[1] - np.log2(measurement)) < 0.4
            if measurement == 1.0:
                # Under 4x gyro noise the 1x random walk (3.4e-4 rad/s over 10 s) is
                # lost in the white noise, so the process multiple stays open there.
                assert abs(mean_log[0] - np.log2(process)) < 1.0


def test_equal_weights_leave_the_classifier_as_it_was(
    marginal: MarginalLikelihoodClassifier, flown: Any
) -> None:
    telemetry = _telemetry(flown, 1, 0, 20)
    offset = initial_offset(marginal.scenario_, telemetry)
    assert offset is not None
    plain = marginal.conditioned_on_offset(offset.process_variance, offset.measurement_variance)
    equal = np.full(len(marginal.grid_), -np.log(len(marginal.grid_)))
    weighted = marginal.conditioned_on_offset(
        offset.process_variance, offset.measurement_variance, equal
    )
    series = np.asarray(flown.omega_measured[1, 0, 10 * 20 :])[None] - offset.offset_rad_s
    np.testing.assert_allclose(weighted.transform(series), plain.transform(series), rtol=1e-12)
    with pytest.raises(InputError, match="log probabilities"):
        marginal.conditioned_on_offset(
            offset.process_variance, offset.measurement_variance, equal + 1.0
        )


def test_a_thruster_pulse_before_the_start_is_named_in_the_verdict(
    drifting_paper: Scenario, marginal: MarginalLikelihoodClassifier
) -> None:
    # One thruster at full duty for 1 s, 3 s before the stated start (10 Hz, 30 s before
    # it): the samples there measure the offset and the noise level, and the step spoils
    # both. Most verdicts were "ambiguous" and none said why; now each says when the
    # rates changed, the status unchanged, and the window it names leaves the step out.
    coast, quiet = 30, [[0] * drifting_paper.n_thrusters]
    pulsed = quiet * coast + GOOD_SEQUENCE
    pulsed[coast - 3] = [4, 0, 0, 0, 0, 0]
    statuses, named = [], []
    for sequence, seed in ((quiet * coast + GOOD_SEQUENCE, 41), (pulsed, 41)):
        result = simulate(drifting_paper, sequence, 1, np.random.default_rng(seed))
        for k in range(drifting_paper.n_candidates):
            telemetry = Telemetry(
                time_s=(result.time_s[1::2] - coast).tolist(),
                omega_rad_s=result.omega_measured[k, 0, 1::2].tolist(),
                sequence_start=0.0,
            )
            verdict = identify(marginal, telemetry)
            if sequence is not pulsed:
                assert verdict.status == "identified" and verdict.candidate_index == k
                assert verdict.pre_start_activity_hint is None
                continue
            statuses.append(verdict.status)
            hint = verdict.pre_start_activity_hint
            assert hint is not None and "before the sequence start" in hint
            assert -3.5 <= verdict.pre_start_activity_at_s <= -2.5
            assert verdict.pre_start_activity_sigmas > 8.0
            assert abs(verdict.pre_start_activity_step_deg_s[0]) > 0.5
            np.testing.assert_allclose(
                verdict.pre_start_activity_step_deg_s,
                np.degrees(verdict.pre_start_activity_step_rad_s),
            )
            # In the text where the status is not the name; the status is as it was.
            assert verdict.verdict.endswith(f". Hint: {hint}") == (verdict.status != "identified")
            shorter = float(hint.rsplit("pre_start_window_s ", 1)[1].split()[0])
            assert 1.0 <= shorter <= 2.0
            again = identify(marginal, telemetry, pre_start_window_s=shorter)
            assert again.candidate_index == k and again.pre_start_activity_hint is None
            named.append(again.status == "identified")
    assert "ambiguous" in statuses
    assert sum(named) > statuses.count("identified")
