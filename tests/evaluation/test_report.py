"""The HTML report speaks as the dashboard does: thrusters from 1, the same 10–90 % band,
an F1 axis ticked at round values, NSGA-II's best so far with its polish start marked."""

from __future__ import annotations

import numpy as np
import pytest

from inertia_id import Scenario, simulate
from inertia_id.evaluation.report import (
    BAND_PERCENTILES,
    _search_rows,
    learning_curve_figure,
    polish_start_timesteps,
    response_figure,
    sequence_figure,
)
from inertia_id.search import ScorerSettings, cem_search
from inertia_id.search.operator import OperatorSettings
from inertia_id.search.pareto import pareto_search


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


def test_an_nsga2_curve_marks_where_its_polish_starts_and_names_its_lines() -> None:
    """NSGA-II's curve is its generations, then its polish rounds: the report drew both as
    one line with nothing to say where the one ends, and named the lines "best F1 so
    far" and "mean F1 of the episodes' sequences" (its score is a predicted accuracy)."""
    found = pareto_search(
        Scenario.paper(),
        sequence_length=2,
        seed=1,
        operator=OperatorSettings(n_realisations=4),
        nsga2_params={"population": 8, "generations": 2, "polish_iterations": 2},
        fresh_realisations=6,
    )
    assert len(found.curve) > 2
    start = found.curve[1].timesteps
    assert polish_start_timesteps(found) == start
    figure = learning_curve_figure(found)
    assert [(shape.x0, shape.x1) for shape in figure.layout.shapes] == [(start, start)]
    assert [a.text for a in figure.layout.annotations] == ["polish starts"]
    names = [trace.name for trace in figure.data]
    assert "best predicted accuracy so far" in names
    assert "predicted accuracy: mean of the generation (polish round)" in names
    assert figure.layout.yaxis2.title.text == "predicted accuracy"
    # NSGA-II has no episode reward: the left axis held an all-null "mean episode
    # reward" line; it is the residual rate of the most accurate so far, as on the job
    # page, with deg/s beside rad/s.
    assert "mean episode reward" not in names
    assert figure.layout.yaxis.title.text == "residual rate (rad/s)"
    rates = figure.data[0]
    assert list(rates.y) == [p.best_residual_rate_rad_s for p in found.curve]
    assert list(rates.customdata) == pytest.approx(
        [np.degrees(p.best_residual_rate_rad_s) for p in found.curve]
    )
    assert "deg/s" in rates.hovertemplate
    rows = dict(_search_rows(found))
    assert rows["search's predicted accuracy (at its design noise)"] == f"{found.best.f1:.3f}"
    assert "search F1 (its own noise draw)" not in rows


def test_a_search_without_polish_rounds_has_no_polish_mark() -> None:
    found = cem_search(
        Scenario.paper(),
        sequence_length=1,
        total_timesteps=32,
        population=16,
        seed=0,
        settings=ScorerSettings(n_realisations=4, objective="separability"),
        patience_episodes=None,
        n_fresh_draws=1,
    )
    assert polish_start_timesteps(found) is None
    assert not learning_curve_figure(found).layout.shapes


def test_each_response_row_gives_deg_s_beside_rad_s(
    paper: Scenario, good_sequence: np.ndarray
) -> None:
    """As the dashboard's rate plots do: a deg/s axis on the right of each rad/s one, its
    range the same span in degrees (the report gave rad/s alone)."""
    result = simulate(paper, good_sequence, 20, np.random.default_rng(0))
    layout = response_figure(result).layout
    axes = [layout[name] for name in sorted(layout) if name.startswith("yaxis")]
    rad = [a for a in axes if a.title.text == "rad/s"]
    deg = [a for a in axes if a.title.text == "deg/s"]
    assert len(rad) == len(deg) == 3
    for left, right in zip(rad, deg, strict=True):
        assert right.side == "right"
        assert np.allclose(np.degrees(left.range), right.range)
    # The span holds every band of its row.
    bands = result.omega_measured
    for axis, left in enumerate(rad):
        low = np.percentile(bands[..., axis], 10, axis=1).min()
        high = np.percentile(bands[..., axis], 90, axis=1).max()
        assert left.range[0] <= low and high <= left.range[1]
