"""A self-contained HTML report of a pipeline run (Plotly charts, no network needed).

Its conventions are the dashboard's: thrusters are numbered from 1, and a response band
runs from the 10th to the 90th percentile of the realisations (:data:`BAND_PERCENTILES`).
"""

from __future__ import annotations

import html
import math
import os
from typing import TYPE_CHECKING, Any

import numpy as np
import plotly.graph_objects as go
import plotly.io as pio
from plotly.subplots import make_subplots

from ..files import write_whole
from ..physics.scenario import Scenario
from ..physics.simulate import SimulationResult
from .sweep import SweepResult

if TYPE_CHECKING:
    from ..classifiers.registry import CandidateClassifier
    from ..search import SearchResult

__all__ = [
    "BAND_PERCENTILES",
    "accuracy_figure",
    "learning_curve_figure",
    "polish_start_timesteps",
    "response_figure",
    "sequence_figure",
    "write_report",
]

_COLOURS = [
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#9467bd",
    "#ff7f0e",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
]


#: The band drawn around each candidate's mean response (percentiles of the
#: realisations), the same as the dashboard's (``GET /scenarios/{id}/response``).
BAND_PERCENTILES = (10.0, 90.0)


def _rgba(hex_colour: str, alpha: float) -> str:
    r, g, b = (int(hex_colour[i : i + 2], 16) for i in (1, 3, 5))
    return f"rgba({r},{g},{b},{alpha})"


def response_figure(result: SimulationResult) -> go.Figure:
    """Measured ω per axis: each candidate's mean, with a band from the 10th to the
    90th percentile of its realisations (:data:`BAND_PERCENTILES`)."""
    fig = make_subplots(
        rows=3,
        cols=1,
        shared_xaxes=True,
        vertical_spacing=0.04,
        subplot_titles=("ω_x", "ω_y", "ω_z"),
        specs=[[{"secondary_y": True}]] * 3,
    )
    t = result.time_s
    # Each row's extent over every band, for its rad/s axis and its deg/s twin.
    extent = [np.inf, -np.inf] * 3
    for k, name in enumerate(result.candidate_names):
        colour = _COLOURS[k % len(_COLOURS)]
        series = result.omega_measured[k]
        low, mean, high = (
            np.percentile(series, BAND_PERCENTILES[0], axis=0),
            series.mean(axis=0),
            np.percentile(series, BAND_PERCENTILES[1], axis=0),
        )
        for axis in range(3):
            row = axis + 1
            extent[2 * axis] = min(extent[2 * axis], float(low[:, axis].min()))
            extent[2 * axis + 1] = max(extent[2 * axis + 1], float(high[:, axis].max()))
            fig.add_trace(
                go.Scatter(
                    x=np.concatenate([t, t[::-1]]),
                    y=np.concatenate([high[:, axis], low[::-1, axis]]),
                    fill="toself",
                    fillcolor=_rgba(colour, 0.15),
                    line={"width": 0},
                    hoverinfo="skip",
                    showlegend=False,
                    legendgroup=name,
                ),
                row=row,
                col=1,
            )
            fig.add_trace(
                go.Scatter(
                    x=t,
                    y=mean[:, axis],
                    name=name,
                    legendgroup=name,
                    showlegend=axis == 0,
                    line={"color": colour, "width": 1.5},
                ),
                row=row,
                col=1,
            )
    # A flight team reads rates in deg/s: each row has a deg/s axis on the right, its
    # range the rad/s axis's times 180/π (an empty trace places it; rad/s alone before).
    for axis in range(3):
        row = axis + 1
        low_rad, high_rad = extent[2 * axis], extent[2 * axis + 1]
        pad = 0.05 * (high_rad - low_rad) or 1e-6
        span = [low_rad - pad, high_rad + pad]
        fig.add_trace(
            go.Scatter(x=[t[0]], y=[None], showlegend=False, hoverinfo="skip"),
            row=row,
            col=1,
            secondary_y=True,
        )
        fig.update_yaxes(title_text="rad/s", range=span, row=row, col=1, secondary_y=False)
        fig.update_yaxes(
            title_text="deg/s",
            range=[math.degrees(v) for v in span],
            showgrid=False,
            row=row,
            col=1,
            secondary_y=True,
        )
    fig.update_xaxes(title_text="time since sequence start (s)", row=3, col=1)
    low, high = (f"{p:g}" for p in BAND_PERCENTILES)
    fig.update_layout(title=f"Gyro response per candidate (mean, {low}–{high} % band)", height=750)
    return fig


def accuracy_figure(sweep: SweepResult) -> go.Figure:
    """Accuracy vs noise multiple with Wilson 95 % intervals, one line per noise.

    The sweep's ceiling (per-candidate Gaussians fitted at each noise level: dashed) and
    other classifiers (dotted) are drawn in the colour of the noise they were scored under.
    """
    fig = go.Figure()
    names = {
        "process": "process noise (disturbance torque)",
        "measurement": "measurement noise (gyro)",
    }
    for i, noise in enumerate(("process", "measurement")):
        points = sweep.curve(noise)
        if not points:
            continue
        x = [p.multiple for p in points]
        y = [p.accuracy for p in points]
        fig.add_trace(
            go.Scatter(
                x=x,
                y=y,
                mode="lines+markers",
                name=names[noise],
                line={"color": _COLOURS[i]},
                error_y={
                    "type": "data",
                    "symmetric": False,
                    "array": [p.ci_high - p.accuracy for p in points],
                    "arrayminus": [p.accuracy - p.ci_low for p in points],
                },
            )
        )
    lines = {**sweep.others, "ceiling": sweep.ceiling} if sweep.ceiling else dict(sweep.others)
    for label, others in lines.items():
        for i, noise in enumerate(("process", "measurement")):
            points = [p for p in others if p.noise == noise]
            if not points:
                continue
            fig.add_trace(
                go.Scatter(
                    x=[p.multiple for p in points],
                    y=[p.accuracy for p in points],
                    mode="lines",
                    name=f"{label}, {names[noise].split(' (')[0]}",
                    line={"color": _COLOURS[i], "dash": "dash" if label == "ceiling" else "dot"},
                )
            )
    fig.update_layout(
        title=f"Accuracy vs noise ({sweep.metric}, "
        f"{sweep.n_test_per_candidate} test series per candidate per point)",
        xaxis_title="noise multiple of the training level (×)",
        yaxis_title="accuracy",
        yaxis_range=[0, 1.02],
        height=450,
    )
    return fig


def sequence_figure(scenario: Scenario, sequence: np.ndarray) -> go.Figure:
    """Commanded duty of each thruster over time, as steps; thrusters numbered from 1."""
    duties = scenario.duties(sequence)
    step = scenario.timing.step_duration_s
    t = np.arange(len(duties) + 1) * step
    fig = go.Figure()
    for j in range(duties.shape[1]):
        fig.add_trace(
            go.Scatter(
                x=t,
                y=np.append(duties[:, j], duties[-1, j]),
                line={"shape": "hv", "color": _COLOURS[j % len(_COLOURS)]},
                name=f"thruster {j + 1}",
            )
        )
    fig.update_layout(
        title="Actuation sequence",
        xaxis_title="time (s)",
        yaxis_title="duty (fraction of full thrust)",
        yaxis_range=[-0.05, 1.05],
        height=350,
    )
    return fig


def polish_start_timesteps(search: SearchResult) -> int | None:
    """The environment steps at NSGA-II's last generation, where its polish rounds begin
    on the curve; None for another method or a curve with no polish round. The
    generations are the curve's first points (fewer when the search stopped in them)."""
    curve = search.curve
    if search.method != "nsga2" or not curve:
        return None
    settings = search.settings.get("nsga2") or {}
    generations = min(len(curve), int(settings.get("generations", len(curve))))
    return curve[generations - 1].timesteps if 0 < generations < len(curve) else None


def learning_curve_figure(search: SearchResult) -> go.Figure:
    """Mean episode reward (left axis) and mean / best F1 (right axis) vs environment steps;
    for NSGA-II, which has no episode reward, the residual rate of the most accurate
    feasible sequence so far (left, rad/s, deg/s in its hover) and its predicted accuracy
    (right), as the dashboard's job page draws them."""
    fig = make_subplots(specs=[[{"secondary_y": True}]])
    x = [p.timesteps for p in search.curve]
    # NSGA-II's score is a predicted accuracy, its mean one of a generation or a polish
    # round's neighbours (:func:`~inertia_id.search.pareto.pareto_search`).
    pareto = search.method == "nsga2"
    if pareto:
        # Its curve's mean_episode_reward is null throughout: the left axis was titled
        # "mean episode reward", ranged -1 to 4 and held nothing.
        rates = [p.best_residual_rate_rad_s for p in search.curve]
        fig.add_trace(
            go.Scatter(
                x=x,
                y=rates,
                customdata=[None if r is None else math.degrees(r) for r in rates],
                mode="lines+markers",
                name="residual rate of the most accurate so far (rad/s)",
                line={"color": _COLOURS[0]},
                hovertemplate="%{y:.4g} rad/s (%{customdata:.4g} deg/s)<extra></extra>",
            ),
            secondary_y=False,
        )
    else:
        fig.add_trace(
            go.Scatter(
                x=x,
                y=[p.mean_episode_reward for p in search.curve],
                mode="lines+markers",
                name="mean episode reward",
                line={"color": _COLOURS[0]},
            ),
            secondary_y=False,
        )
    score = "predicted accuracy" if pareto else "F1"
    mean = "mean of the generation (polish round)" if pareto else "mean of the episodes' sequences"
    for i, (name, values) in enumerate(
        (
            (f"{score}: {mean}", [p.mean_f1 for p in search.curve]),
            (f"best {score} so far", [p.best_f1 for p in search.curve]),
        )
    ):
        fig.add_trace(
            go.Scatter(
                x=x,
                y=values,
                mode="lines",
                name=name,
                line={"color": _COLOURS[i + 1], "dash": "dot" if i == 0 else "solid"},
            ),
            secondary_y=True,
        )
    start = polish_start_timesteps(search)
    if start is not None:
        fig.add_vline(
            x=start,
            line={"dash": "dash", "color": "#555", "width": 1},
            annotation={"text": "polish starts", "xanchor": "left", "font": {"size": 11}},
        )
    fig.update_layout(
        title=f"Search ({search.method}): learning curve",
        xaxis_title="environment steps",
        height=400,
    )
    fig.update_yaxes(
        title_text="residual rate (rad/s)" if pareto else "mean episode reward", secondary_y=False
    )
    # Round ticks of its own (0, 0.2, ..., 1): Plotly would otherwise align them with
    # the reward axis's ticks, at values such as 0.078 and 0.245.
    fig.update_yaxes(
        title_text=score,
        range=[0, 1.02],
        tickmode="linear",
        tick0=0,
        dtick=0.2,
        showgrid=False,
        secondary_y=True,
    )
    return fig


def _table(rows: list[tuple[str, Any]]) -> str:
    cells = "".join(
        f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>" for k, v in rows
    )
    return f"<table>{cells}</table>"


def _search_rows(search: SearchResult | None) -> list[tuple[str, Any]]:
    if search is None:
        return [("sequence from", "given (no search)")]
    return [
        (
            "sequence from",
            f"{search.method} search, {search.timesteps} environment steps, "
            f"{search.wall_time_s:.0f} s, stopped: {search.stopped}",
        ),
        (
            # NSGA-II's best.f1 is the accuracy it predicts at its design noise, not an F1
            # (the fresh draws' figure below is the clustering F1).
            "search's predicted accuracy (at its design noise)"
            if search.method == "nsga2"
            else "search F1 (its own noise draw)",
            f"{search.best.f1:.3f}",
        ),
        (
            f"F1 on {len(search.fresh.f1)} fresh draws (mean, min)",
            f"{search.fresh.f1_mean:.3f}, {search.fresh.f1_min:.3f}",
        ),
    ]


def write_report(
    path: str | os.PathLike[str],
    *,
    scenario: Scenario,
    sequence: np.ndarray,
    result: SimulationResult,
    classifier: CandidateClassifier,
    sweep: SweepResult | None = None,
    search: SearchResult | None = None,
    seed: int | None = None,
) -> None:
    """Write the HTML report: summary, candidates, search, sequence, responses, accuracy,
    whole or not at all (:func:`~inertia_id.files.write_whole`).

    :param seed: the run's seed, shown with the version of inertia-id that wrote the
        report, so that the run can be made again (``summary.json`` has the seed too).
    """
    from .. import __version__

    candidates = "".join(
        f"<tr><td>{html.escape(c.name)}</td><td>"
        f"{', '.join(f'{m:.2f}' for m in c.principal_moments_kg_m2)}</td></tr>"
        for c in scenario.inertia_candidates
    )
    confusion = "".join(
        "<tr><th>" + html.escape(name) + "</th>" + "".join(f"<td>{v}</td>" for v in row) + "</tr>"
        for name, row in zip(
            classifier.candidate_names_, classifier.confusion_.tolist(), strict=True
        )
    )
    summary = _table(
        [
            ("scenario", scenario.name),
            ("sequence (level indices, one row per step)", np.asarray(sequence).tolist()),
            ("metric", classifier.metric),
            ("training F1 (best cluster matching)", f"{classifier.f1_:.3f}"),
            ("training accuracy", f"{classifier.accuracy_:.3f}"),
            ("fuel use (total angular impulse)", f"{result.impulse_nms:.3f} N m s"),
            (
                "mean final rate |ω|",
                f"{result.mean_final_rate_rad_s:.4g} rad/s "
                f"({math.degrees(result.mean_final_rate_rad_s):.4g} deg/s)",
            ),
            *_search_rows(search),
            *([] if seed is None else [("seed", seed)]),
            ("inertia-id version", __version__),
        ]
    )
    figures = [sequence_figure(scenario, sequence), response_figure(result)]
    if search is not None:
        figures.insert(0, learning_curve_figure(search))
    if sweep is not None:
        figures.append(accuracy_figure(sweep))
    charts = "".join(
        pio.to_html(fig, full_html=False, include_plotlyjs="inline" if i == 0 else False)
        for i, fig in enumerate(figures)
    )
    names = "".join(f"<th>{html.escape(n)}</th>" for n in classifier.candidate_names_)
    document = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>inertia-id report: {html.escape(scenario.name)}</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; }}
table {{ border-collapse: collapse; margin: 1em 0; }}
th, td {{ border: 1px solid #ccc; padding: 4px 8px; text-align: left; }}
</style></head><body>
<h1>inertia-id report: {html.escape(scenario.name)}</h1>
{summary}
<h2>Candidates (principal moments, kg m²)</h2>
<table><tr><th>candidate</th><th>principal moments</th></tr>{candidates}</table>
<h2>Training confusion matrix (rows: true, columns: predicted)</h2>
<table><tr><th></th>{names}</tr>{confusion}</table>
{charts}
</body></html>
"""
    write_whole(path, document)
