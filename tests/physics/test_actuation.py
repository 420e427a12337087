"""The delivered duty's moments under clipped jitter: against the truncated normal's
closed form, against sampling, and at the limits of a vanishing and a large sigma."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm, truncnorm

from inertia_id import InputError
from inertia_id.physics.actuation import (
    MAX_MOMENT_SIGMA,
    delivered_duty,
    delivered_duty_moments,
)

# Near off, inside, near and at full duty, and past it (held at full by the clip).
DUTIES = [0.001, 0.05, 0.3, 0.5, 0.97, 1.0, 1.5]


def clipped_normal_moments(duty: float, sigma: float) -> tuple[float, float]:
    """The censored normal written out from scipy's truncated normal: 0 with
    probability P(Y ≤ 0), 1 with P(Y ≥ 1), the truncated normal on (0, 1) otherwise."""
    low, high = (0.0 - duty) / sigma, (1.0 - duty) / sigma
    inside = norm.cdf(high) - norm.cdf(low)
    above = norm.sf(high)
    kept = truncnorm(low, high, loc=duty, scale=sigma)
    mean = above + inside * kept.mean()
    square = above + inside * (kept.var() + kept.mean() ** 2)
    return float(mean), float(square - mean**2)


@pytest.mark.parametrize("sigma", [1e-3, 0.02, 0.3, 1.0, 10.0])
@pytest.mark.parametrize("duty", DUTIES)
def test_the_moments_are_the_clipped_normals_closed_form(duty: float, sigma: float) -> None:
    mean, variance = delivered_duty_moments(np.array(duty), sigma)
    if (1.0 - duty) / sigma < -30:
        # truncnorm cannot be built on an interval of probability 0: the clip holds full.
        want_mean, want_variance = 1.0, 0.0
    else:
        want_mean, want_variance = clipped_normal_moments(duty, sigma)
    assert mean == pytest.approx(want_mean, rel=1e-9)
    assert variance == pytest.approx(want_variance, rel=1e-8)


@pytest.mark.parametrize("sigma", [0.1, 1.0, 10.0])
@pytest.mark.parametrize("duty", [0.05, 0.5, 1.0, 1.5])
def test_the_moments_match_a_million_clipped_draws(duty: float, sigma: float) -> None:
    """Within five standard errors of the sample mean and of the sample variance (the
    latter's from the spread of the squared deviations), for large sigma as well."""
    jitter = sigma * np.random.default_rng(11).standard_normal(1_000_000)
    draws = delivered_duty(np.array(duty), jitter)
    mean, variance = delivered_duty_moments(np.array(duty), sigma)
    error = draws.std() / math.sqrt(draws.size)
    squares = (draws - draws.mean()) ** 2
    variance_error = squares.std() / math.sqrt(draws.size)
    assert abs(mean - draws.mean()) < 5 * error, (mean, draws.mean(), error)
    assert abs(variance - draws.var()) < 5 * variance_error + 1e-15, (variance, draws.var())


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("sigma", [1e-20, 1e-160, 1e-300, 5e-324, 0.0])
def test_a_vanishing_sigma_gives_the_clipped_duty_and_no_spread(sigma: float) -> None:
    duty = np.array([-0.2, 0.0, 1e-9, 0.5, 1.0, 1.5])
    with np.errstate(all="raise"):
        mean, variance = delivered_duty_moments(duty, sigma)
    # Off below 0 and at 0; every firing duty delivered whole, clipped to full past it.
    np.testing.assert_array_equal(mean, [0.0, 0.0, 1e-9, 0.5, 1.0, 1.0])
    assert (variance >= 0.0).all()
    assert (variance <= sigma * sigma).all()
    assert variance[[0, 1, 5]].tolist() == [0.0, 0.0, 0.0]


def test_the_limits_are_approached_as_sigma_shrinks() -> None:
    duty = np.array([0.5, 1.0])
    for sigma in [1e-2, 1e-4, 1e-8, 1e-12]:
        mean, variance = delivered_duty_moments(duty, sigma)
        assert mean[0] == 0.5
        assert mean[1] == pytest.approx(1.0 - sigma / math.sqrt(2.0 * math.pi), rel=1e-15)
        np.testing.assert_allclose(
            variance, [sigma**2, (0.5 - 0.5 / math.pi) * sigma**2], rtol=1e-12
        )


@pytest.mark.parametrize("sigma", [-0.1, math.nan, math.inf, -math.inf, 2 * MAX_MOMENT_SIGMA])
def test_a_sigma_out_of_range_is_refused_naming_it(sigma: float) -> None:
    with pytest.raises(InputError, match=rf"duty jitter sigma = {sigma!r} \(fraction"):
        delivered_duty_moments(np.array([0.5]), sigma)
