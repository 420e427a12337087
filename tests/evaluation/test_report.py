"""The HTML report speaks as the dashboard does: thrusters from 1, the same 10–90 % band,
an F1 axis ticked at round values."""

from __future__ import annotations

import numpy as np
import pytest

from inertia_id import Scenario, simulate
from inertia_id.evaluation.report import (
    BAND_PERCENTILES,
    learning_curve_figure,
    response_figure,
    sequence_figure,
)
from inertia_id.search import ScorerSettings, cem_search


def test_thrusters_are_numbered_from_one(paper: Scenario, good_sequence: np.ndarray) -> None:
    names = [trace.name for trace in sequence_figure(paper, good_sequence).data]
    assert names == [f"thruster {j}" for j in range(1, paper.n_thrusters + 1)]


def test_the_band_is_the_dashboards_10_to_90_percent(
    paper: Scenario, good_sequence: np.ndarray
) -> None:
    assert BAND_PERCENTILES == (10.0, 90.0)
    result = simulate(paper, good_sequence, 20, np.random.default_rng(0))
    figure = response_figure(result)
    assert "10–90 % band" in figure.layout.title.text
    band = figure.data[0]  # candidate 0, ω_x: upper edge then the lower edge reversed
    series = result.omega_measured[0][:, :, 0]
    n = len(result.time_s)
    assert np.allclose(band.y[:n], np.percentile(series, 90, axis=0))
    assert np.allclose(band.y[n:], np.percentile(series, 10, axis=0)[::-1])


@pytest.mark.parametrize("seed", [0])
def test_the_f1_axis_ticks_at_round_values(seed: int) -> None:
    tiny = Scenario.paper().model_copy(deep=True)
    found = cem_search(
        tiny,
        sequence_length=1,
        total_timesteps=32,
        population=16,
        seed=seed,
        settings=ScorerSettings(n_realisations=4, objective="separability"),
        patience_episodes=None,
        n_fresh_draws=1,
    )
    axis = learning_curve_figure(found).layout.yaxis2
    assert (axis.tickmode, axis.tick0, axis.dtick) == ("linear", 0, 0.2)
