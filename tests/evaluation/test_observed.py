"""Slow telemetry on the grid (GitHub issue 13): the likelihood kinds evaluate the exact
Gaussian marginal of the measured grid points only, not the interpolated ones."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import Scenario, simulate
from inertia_id.classifiers.likelihood import LikelihoodClassifier
from inertia_id.classifiers.marginal import MarginalLikelihoodClassifier
from inertia_id.errors import InputError
from inertia_id.evaluation.identify import identify, identify_online
from inertia_id.evaluation.telemetry import Telemetry, resample, resample_observed


@pytest.fixture(scope="module")
def likelihood(drifting_paper: Scenario) -> LikelihoodClassifier:
    return LikelihoodClassifier().fit_scenario(
        drifting_paper, GOOD_SEQUENCE, 30, np.random.default_rng(22)
    )


@pytest.fixture(scope="module")
def fresh(drifting_paper: Scenario) -> Any:
    """Simulated at the scenario's 20 Hz: every 2nd / 20th sample is 10 Hz / 1 Hz
    telemetry exactly on the grid."""
    return simulate(drifting_paper, GOOD_SEQUENCE, 4, np.random.default_rng(23))


def _telemetry(fresh: Any, k: int, i: int, every: int) -> Telemetry:
    # Samples at the end of each period (k / 20 s): every `every`-th from the last back.
    pick = slice(every - 1, None, every)
    return Telemetry(
        time_s=fresh.time_s[pick].tolist(),
        omega_rad_s=fresh.omega_measured[k, i][pick].tolist(),
    )


def test_observed_mask_marks_the_measured_grid_points(fresh: Any) -> None:
    grid = np.asarray(fresh.time_s)
    for every, count in ((1, 80), (2, 40), (20, 4)):
        series, observed = resample_observed(_telemetry(fresh, 0, 0, every), grid)
        np.testing.assert_array_equal(series, resample(_telemetry(fresh, 0, 0, every), grid))
        assert observed.sum() == count
        np.testing.assert_array_equal(np.flatnonzero(observed), np.arange(every - 1, 80, every))
    # Off the grid (10 Hz shifted by a quarter period): each sample's nearest grid time.
    off = Telemetry(time_s=(grid[1::2] - 0.0125).tolist(), omega_rad_s=[[0.0] * 3] * 40)
    np.testing.assert_array_equal(
        np.flatnonzero(resample_observed(off, grid)[1]), np.arange(1, 80, 2)
    )
    # Faster than the grid: averaged into every grid time, every one counts.
    fast = Telemetry(time_s=np.arange(0.01, 4.0, 0.01).tolist(), omega_rad_s=[[0.0] * 3] * 399)
    assert resample_observed(fast, grid)[1].all()


@pytest.mark.parametrize("kind", ["marginal", "likelihood"])
def test_all_true_mask_is_bit_identical(kind: str, request: Any, fresh: Any) -> None:
    model = request.getfixturevalue(kind)
    X = fresh.dataset()[0]
    everything = np.ones(model.length_, dtype=bool)
    np.testing.assert_array_equal(model.transform_observed(X, everything), model.transform(X))
    for a, b in zip(
        model.predict_posterior(X, observed=everything), model.predict_posterior(X), strict=True
    ):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(
        model.posterior_over_time(X, observed=everything),
        model.posterior_over_time(X),
        strict=True,
    ):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(model.novelty_thresholds(1.0), model.novelty_thresholds())
    assert model.observed_fraction(everything) == 1.0


@pytest.mark.parametrize("kind", ["marginal", "likelihood"])
def test_sub_block_is_the_exact_marginal(kind: str, request: Any, fresh: Any) -> None:
    """The sub-block's distances equal a classifier of the measured values alone, and
    its prefixes the leading blocks."""
    model = request.getfixturevalue(kind)
    X = fresh.dataset()[0]
    observed = np.zeros(model.length_, dtype=bool)
    observed[1::2] = True
    values = (np.flatnonzero(observed)[:, None] * 3 + np.arange(3)).ravel()
    distances = model.transform_observed(X, observed)
    prefix = model._observed_prefix_distances(model._check_input(X), values)
    assert prefix.shape == (len(X), 40, model.n_candidates_)
    np.testing.assert_allclose(prefix[:, -1], distances, rtol=1e-9)
    if kind == "likelihood":
        means = model.means_.reshape(model.n_candidates_, -1)[:, values]
        covariance = model.covariance_[np.ix_(values, values)]
        F = X.reshape(len(X), -1)[:, values]
        diff = F[:, None] - means[None]
        direct = np.sqrt(np.einsum("nki,ij,nkj->nk", diff, np.linalg.inv(covariance), diff))
        np.testing.assert_allclose(distances, direct, rtol=1e-7)
    # The posterior over time moves at measured points only.
    candidates, _ = model.posterior_over_time(X, observed=observed)
    np.testing.assert_array_equal(candidates[:, 0::2][:, 1:], candidates[:, 1:-1:2])


@pytest.mark.parametrize(("every", "named", "stopped"), [(2, 15, 15), (20, 8, 4)])
def test_slow_telemetry_is_identified_on_the_measured_points(
    every: int, named: int, stopped: int, marginal: MarginalLikelihoodClassifier, fresh: Any
) -> None:
    identified = decided = 0
    for k in range(marginal.n_candidates_):
        for i in range(4):
            telemetry = _telemetry(fresh, k, i, every)
            verdict = identify(marginal, telemetry)
            assert verdict.candidate_index == k
            assert verdict.status in ("identified", "ambiguous"), verdict.verdict
            identified += verdict.status == "identified"
            online = identify_online(marginal, telemetry)
            # The off-candidates factor after every sample: none before the first
            # measurement, the verdict's once all are in.
            near = np.asarray(online.off_candidates_log_bayes, dtype=float)
            first = next(j for j, t in enumerate(online.time_s) if round(t * 20) % every == 0)
            assert np.isnan(near[:first]).all() and np.isfinite(near[first:]).all()
            assert near[-1] == pytest.approx(verdict.off_candidates_log_bayes, abs=1e-6)
            if online.decided:
                decided += 1
                assert online.decision_off_candidates_log_bayes is not None
                assert online.decision_off_candidates_log_bayes < 0.0
                assert online.candidate_index == k
                # Decided at a measured sample (the posterior moves only there).
                assert round(online.decision_time_s * 20) % every == 0
    # 4 measurements at 1 Hz say less than 40 at 10 Hz; never a wrong candidate.
    assert identified >= named and decided >= stopped


def test_slow_novelty_threshold_follows_the_tail(marginal: MarginalLikelihoodClassifier) -> None:
    tail = marginal.novelty_tail_
    assert tail is not None
    full = marginal.novelty_thresholds()
    for fraction in (0.5, 0.05):
        part = marginal.novelty_thresholds(fraction)
        np.testing.assert_allclose(
            tail.log_sf(part, fraction), tail.log_sf(full), rtol=1e-6, atol=1e-9
        )
        assert np.all(part < full)


def test_observed_mask_is_checked(marginal: MarginalLikelihoodClassifier, fresh: Any) -> None:
    X = fresh.dataset()[0]
    with pytest.raises(InputError, match="booleans"):
        marginal.transform_observed(X, np.ones(3, dtype=bool))
    with pytest.raises(InputError, match="no grid point"):
        marginal.transform_observed(X, np.zeros(marginal.length_, dtype=bool))


@pytest.mark.parametrize("jitter_ms", [1.0, 10.0, 25.0])
def test_slow_stamps_off_the_grid_count_their_samples_not_the_interpolation(
    paper: Scenario, jitter_ms: float
) -> None:
    """1 Hz telemetry with 30 s before the start (a residual rate and a gyro bias drawn),
    no sample at the start itself, stamps up to ``jitter_ms`` off the 20 Hz grid.

    One stamp off the grid made every grid time count as measured: 80 values, most of
    them interpolated across the thrusters' start between the samples at -1 s and +1 s,
    and the default classifier answered 11 or 12 of 20 with a confident wrong candidate
    and none right (helper-22 found it on Basilisk telemetry). Each sample now counts at
    its nearest grid time: 20 of 20 right at each jitter.
    """
    from inertia_id import preset
    from inertia_id.cli.scenario import _at_rate, _with_coast

    model = MarginalLikelihoodClassifier().fit_scenario(
        paper, GOOD_SEQUENCE, 100, np.random.default_rng(0)
    )
    fast = _at_rate(preset("paper-in-orbit"), 200.0)  # values every 5 ms
    rows, coast_s = _with_coast(fast, np.asarray(GOOD_SEQUENCE), 30.0)
    flown = simulate(fast, rows, 4, np.random.default_rng(1))
    t = flown.time_s - coast_s
    rng = np.random.default_rng(2)
    right = wrong = 0
    for k in range(flown.omega_measured.shape[0]):
        for i in range(4):
            base = np.arange(-29.0, 4.001, 1.0)
            base = base[base != 0.0]
            stamps = base + rng.uniform(-jitter_ms, jitter_ms, base.size) * 1e-3
            pick = np.clip(np.searchsorted(t, stamps), 0, len(t) - 1)  # within 5 ms
            telemetry = Telemetry(
                time_s=stamps.tolist(), omega_rad_s=flown.omega_measured[k, i][pick].tolist()
            )
            grid = paper.sample_times(len(GOOD_SEQUENCE))
            assert int(resample_observed(telemetry, grid)[1].sum()) == 4  # the 4 in it
            verdict = identify(model, telemetry)
            if verdict.status == "identified":
                right += verdict.candidate_index == k
                wrong += verdict.candidate_index != k
    assert wrong == 0 and right >= 18, (right, wrong)


def test_an_averaging_gyro_is_read_at_its_intervals_midpoints(paper: Scenario) -> None:
    """A 1 Hz integrating (delta-angle) gyro: each rate the mean over the second before its
    stamp. Read as instantaneous at the stamp, the default classifier named the wrong
    candidate for 16 of 20 series and the right one for none (a reviewer found 12 of 15
    on Basilisk flights); ``averaged`` reads each at its interval's midpoint: 20 of 20."""
    from inertia_id.cli.scenario import _at_rate

    model = MarginalLikelihoodClassifier().fit_scenario(
        paper, GOOD_SEQUENCE, 100, np.random.default_rng(0)
    )
    flown = simulate(_at_rate(paper, 200.0), np.asarray(GOOD_SEQUENCE), 4, np.random.default_rng(1))
    stamps = [1.0, 2.0, 3.0, 4.0]
    tallies = []
    for averaged in (False, True):
        right = wrong = 0
        for k in range(flown.omega_measured.shape[0]):
            for i in range(4):
                means = flown.omega_measured[k, i].reshape(4, 200, 3).mean(axis=1)
                telemetry = Telemetry(time_s=stamps, omega_rad_s=means.tolist(), averaged=averaged)
                verdict = identify(model, telemetry)
                if verdict.status == "identified":
                    right += verdict.candidate_index == k
                    wrong += verdict.candidate_index != k
        tallies.append((right, wrong))
    assert tallies[0][1] >= 10  # what it was: confidently wrong
    assert tallies[1] == (20, 0)
    # A dropped sample: the next still averages one period, not the gap before it.
    dropped = Telemetry(time_s=[1.0, 2.0, 3.0, 5.0], omega_rad_s=[[0.0] * 3] * 4, averaged=True)
    assert dropped.time_array.tolist() == [0.5, 1.5, 2.5, 4.5]
    assert Telemetry(
        time_s=stamps, omega_rad_s=[[0.0] * 3] * 4, averaged=True
    ).time_array.tolist() == [
        0.5,
        1.5,
        2.5,
        3.5,
    ]


def test_a_downlink_that_covers_one_grid_time_says_so(
    marginal: MarginalLikelihoodClassifier, fresh: Any
) -> None:
    """A partial downlink that stops within half a period of the sequence's first sample
    covers one grid time: the online answer needs two, and said "the classifier's grid
    has 1 time(s)", naming the classifier (whose grid has 80) instead of the telemetry."""
    grid = fresh.time_s
    omega = fresh.omega_measured[0, 0]
    short = Telemetry(
        time_s=[-1.0, float(grid[0]) + 0.01], omega_rad_s=[[0.0, 0.0, 0.0], omega[0].tolist()]
    )
    with pytest.raises(InputError, match="covering only the first sample") as caught:
        identify_online(marginal, short)
    assert "classifier" not in str(caught.value)
    assert f"{grid[0] + 0.01:.6g} s" in str(caught.value)
    # Two grid times: an answer, one posterior per time.
    two = Telemetry(time_s=grid[:2].tolist(), omega_rad_s=omega[:2].tolist())
    assert len(identify_online(marginal, two).time_s) == 2


COARSE_SEQUENCE = [[4, 4, 4, 0, 0, 0], [4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4], [0] * 6]


def _paper_timed(rate_hz: float, step_s: float = 2.0) -> Scenario:
    """The paper's spacecraft with a residual initial rate, ``step_s`` steps, ``rate_hz``."""
    document = Scenario.paper().model_dump()
    document["timing"] = {
        "step_duration_s": step_s,
        "integration_step_s": 0.05,
        "sample_rate_hz": rate_hz,
    }
    document["uncertainty"]["initial_rate_sigma_rad_s"] = 0.002
    return Scenario.model_validate(document)


@pytest.fixture(scope="module")
def coarse() -> Any:
    """The default kind modelled on a 1 Hz grid (the ground segment's own gyro rate),
    2 s steps, the thrusters reversing at 4 s and stopping at 6 s."""
    from inertia_id import train

    return train(_paper_timed(1.0), COARSE_SEQUENCE, 100, np.random.default_rng(0))


def _passes(sequence: Any, seed: int, rate_hz: float = 10.0, step_s: float = 2.0) -> Any:
    """One pass a candidate at ``rate_hz``, from 30 s before the start: (stamps, rates)."""
    before = round(30 / step_s)
    flown = simulate(
        _paper_timed(rate_hz, step_s), [[0] * 6] * before + sequence, 1, np.random.default_rng(seed)
    )
    return flown.time_s - before * step_s, flown.omega_measured[:, 0]


def test_fast_telemetry_on_a_coarse_grid_is_not_called_none_of_the_candidates(
    coarse: Any,
) -> None:
    """A pass downlinked from a 10 Hz gyro: more samples of the same flight, never less
    information than its 1 Hz samples alone. (Each grid time took the mean of the 10 Hz
    samples over the whole grid period around it, which bends the rate where a thruster
    switches on or off at a step boundary by about an eighth of a second's torque, some
    four gyro sigmas here: every genuine pass, one per candidate, was "matches none of
    the candidates", P(none) = 1 for four of five, while the same pass cut to its 1 Hz
    samples named four and called the fifth ambiguous.)"""
    time_s, rates = _passes(COARSE_SEQUENCE, 6)
    whole_second = np.isclose(time_s, np.round(time_s), atol=1e-9)
    fast, slow = [], []
    for omega in rates:
        fast.append(identify(coarse, {"time_s": time_s, "omega_rad_s": omega}))
        slow.append(
            identify(coarse, {"time_s": time_s[whole_second], "omega_rad_s": omega[whole_second]})
        )
    # The control: the 1 Hz samples alone name the candidate flown, or hold back.
    assert [v.status for v in slow].count("identified") >= 4
    assert all(v.candidate_index == k for k, v in enumerate(slow))
    # Ten times the samples: no genuine pass is disowned, and as many are named.
    assert [v.status for v in fast if v.status in ("matches-none", "not-this-sequence")] == []
    assert all(v.candidate_index == k for k, v in enumerate(fast) if v.status == "identified")
    assert [v.status for v in fast].count("identified") >= 4


@pytest.mark.parametrize("offset_s", [0.3, 0.5])
def test_a_gyro_off_a_coarse_grid_is_not_read_across_a_thruster_switch(
    coarse: Any, offset_s: float
) -> None:
    """A 1 Hz gyro whose clock is not the sequence's: its stamps 0.3 or 0.5 s past the
    grid times. Each grid time was read between the samples around it, a second apart,
    and where the thrusters reverse between them (4 s) that is off by up to a quarter
    second's change of acceleration, 10 gyro sigmas: every genuine pass was "matches
    none of the candidates". The likelihood now leaves out the grid times so read
    across a switch, and judges the others, which the interpolation reads right."""
    time_s, rates = _passes(COARSE_SEQUENCE, 7)
    shifted = np.isclose(np.mod(time_s - offset_s + 0.5, 1.0), 0.5, atol=1e-6)
    verdicts = [
        identify(coarse, {"time_s": time_s[shifted], "omega_rad_s": omega[shifted]})
        for omega in rates
    ]
    assert [v.status for v in verdicts if v.status in ("matches-none", "not-this-sequence")] == []
    assert all(v.candidate_index == k for k, v in enumerate(verdicts))
    assert [v.status for v in verdicts].count("identified") >= 4
    # The grid times read across the switches are the ones left out: 4 s (the reversal)
    # and 6 s (the stop), and the start's, 0.3 s after which the first sample comes.
    assert all(v.sequence_measured_fraction < 1.0 for v in verdicts)


def test_telemetry_read_across_a_switch_at_every_grid_time_is_refused_saying_why() -> None:
    """Thrusters reversing every 1 s step on a 1 Hz model, the gyro half a second off
    its grid: every grid time lies between samples on either side of a reversal. No
    grid time can be judged; the refusal says so, not "matches none"."""
    from inertia_id import train

    sequence = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]] * 2
    model = train(_paper_timed(1.0, 1.0), sequence, 100, np.random.default_rng(0))
    time_s, rates = _passes(sequence, 8, step_s=1.0)
    half = np.isclose(np.mod(time_s, 1.0), 0.5, atol=1e-6)
    with pytest.raises(InputError, match="read between samples on either side of a thruster"):
        identify(model, {"time_s": time_s[half], "omega_rad_s": rates[0][half]})
