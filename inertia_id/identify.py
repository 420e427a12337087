"""Which candidate is this spacecraft? Classify measured telemetry.

Telemetry is the gyro's ω samples, with time stamps measured from the start of the
actuation sequence the classifier was trained for. It is resampled (linear
interpolation) onto the classifier's sample grid and compared with every candidate's
centroid. A series farther from its nearest centroid than any training response was
(times the classifier's novelty factor) "matches none": a spacecraft in an unexpected
state is not forced into a class.
"""

from __future__ import annotations

import csv
import io
import json
import os
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel, Field, field_validator, model_validator

from .leastsquares import estimate_inertia

if TYPE_CHECKING:
    from .registry import CandidateClassifier


__all__ = ["Identification", "Telemetry", "identify", "load_telemetry", "parse_telemetry"]

MAX_TELEMETRY_SAMPLES = 200_000


class Telemetry(BaseModel):
    """Gyro telemetry: time stamps (s from the sequence start) and body rates (rad/s)."""

    time_s: list[float] = Field(max_length=MAX_TELEMETRY_SAMPLES)
    omega_rad_s: list[list[float]] = Field(max_length=MAX_TELEMETRY_SAMPLES)

    @field_validator("time_s")
    @classmethod
    def _times(cls, value: list[float]) -> list[float]:
        arr = np.asarray(value, dtype=float)
        if arr.size < 2:
            raise ValueError(f"telemetry needs at least 2 samples, got {arr.size}")
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise ValueError(f"time_s[{bad[0]}] = {value[bad[0]]!r} is not finite")
        steps = np.diff(arr)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            raise ValueError(
                f"time stamps must increase strictly: time_s[{i}] = {value[i]!r}, "
                f"time_s[{i + 1}] = {value[i + 1]!r}"
            )
        return value

    @field_validator("omega_rad_s")
    @classmethod
    def _rates(cls, value: list[list[float]]) -> list[list[float]]:
        for i, row in enumerate(value):
            if len(row) != 3:
                raise ValueError(f"omega_rad_s row {i} has {len(row)} columns, expected 3: {row}")
        arr = np.asarray(value, dtype=float).reshape(-1, 3)
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            i, j = (int(v) for v in bad[0])
            raise ValueError(f"omega_rad_s[{i}][{j}] = {value[i][j]!r} is not finite")
        return value

    @model_validator(mode="after")
    def _lengths(self) -> Telemetry:
        if len(self.time_s) != len(self.omega_rad_s):
            raise ValueError(
                f"{len(self.time_s)} time stamps but {len(self.omega_rad_s)} omega rows"
            )
        return self

    @property
    def time_array(self) -> np.ndarray:
        return np.asarray(self.time_s, dtype=float)

    @property
    def omega_array(self) -> np.ndarray:
        return np.asarray(self.omega_rad_s, dtype=float).reshape(-1, 3)


class Identification(BaseModel):
    """The verdict on one telemetry series.

    ``candidate`` is the nearest candidate even when ``matches_none`` is true, so an
    operator can see what it was closest to; ``matches_none`` says it should not be
    believed.
    """

    candidate_index: int
    candidate: str
    inertia_kg_m2: list[list[float]] | None
    distances: dict[str, float]
    margin: float
    relative_margin: float
    threshold: float
    matches_none: bool
    verdict: str
    estimated_inertia_kg_m2: list[list[float]] | None = None
    estimated_principal_moments_kg_m2: list[float] | None = None
    estimate_condition_number: float | None = None
    poorly_excited: list[str] = []


def parse_telemetry(text: str, *, fmt: str = "auto") -> Telemetry:
    """Parse telemetry from JSON or CSV text.

    JSON: ``{"time_s": [...], "omega_rad_s": [[wx, wy, wz], ...]}``.
    CSV: four columns ``time_s, wx, wy, wz``; a header row is allowed.
    """
    text = text.strip()
    if fmt == "auto":
        fmt = "json" if text.startswith(("{", "[")) else "csv"
    if fmt == "json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"telemetry is not valid JSON: {exc}") from None
        if not isinstance(data, dict):
            raise ValueError("telemetry JSON must be an object with time_s and omega_rad_s")
        return Telemetry.model_validate(data)
    if fmt != "csv":
        raise ValueError(f"telemetry format must be json, csv or auto, got {fmt!r}")
    try:
        rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise ValueError(f"telemetry is not valid CSV: {exc}") from None
    if rows and not _numeric(rows[0][0]):
        rows = rows[1:]
    if len(rows) > MAX_TELEMETRY_SAMPLES:
        raise ValueError(f"telemetry has {len(rows)} rows; at most {MAX_TELEMETRY_SAMPLES}")
    times: list[float] = []
    omegas: list[list[float]] = []
    for n, row in enumerate(rows, start=1):
        if len(row) != 4:
            raise ValueError(
                f"CSV data row {n} has {len(row)} columns, expected 4 (time_s, wx, wy, wz): {row}"
            )
        try:
            values = [float(c) for c in row]
        except ValueError:
            raise ValueError(f"CSV data row {n} is not numeric: {row}") from None
        times.append(values[0])
        omegas.append(values[1:])
    return Telemetry(time_s=times, omega_rad_s=omegas)


def _numeric(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def load_telemetry(path: str | os.PathLike[str]) -> Telemetry:
    """Read telemetry from a .json or .csv file."""
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    suffix = os.fspath(path).lower().rsplit(".", 1)[-1]
    return parse_telemetry(text, fmt=suffix if suffix in ("json", "csv") else "auto")


def resample(telemetry: Telemetry, grid_s: np.ndarray) -> np.ndarray:
    """ω interpolated linearly onto ``grid_s``; the telemetry must cover the grid.

    Half a sample period of slack is allowed at either end, where the nearest sample
    is held.
    """
    t = telemetry.time_array
    slack = 0.5 * float(grid_s[1] - grid_s[0]) if len(grid_s) > 1 else 0.0
    if t[0] > grid_s[0] + slack or t[-1] < grid_s[-1] - slack:
        raise ValueError(
            f"telemetry spans {t[0]:.6g} s to {t[-1]:.6g} s but the sequence needs "
            f"{grid_s[0]:.6g} s to {grid_s[-1]:.6g} s (time from the sequence start)"
        )
    omega = telemetry.omega_array
    return np.stack([np.interp(grid_s, t, omega[:, axis]) for axis in range(3)], axis=-1)


def identify(
    classifier: CandidateClassifier, telemetry: Telemetry | dict[str, Any]
) -> Identification:
    """Classify one telemetry series to a candidate, or say it matches none.

    :param classifier: fitted classifier that carries its scenario and sequence.
    :param telemetry: the response to the classifier's sequence.
    """
    if not isinstance(telemetry, Telemetry):
        telemetry = Telemetry.model_validate(telemetry)
    scenario = getattr(classifier, "scenario_", None)
    sequence = getattr(classifier, "sequence_", None)
    if scenario is None or sequence is None:
        raise ValueError("the classifier does not carry its scenario and sequence")
    grid = scenario.sample_times(len(sequence))
    series = resample(telemetry, grid)
    distances = classifier.transform(series[None])[0]
    order = np.argsort(distances)
    best = int(order[0])
    runner_up = float(distances[order[1]])
    margin = runner_up - float(distances[best])
    threshold = float(classifier.novelty_thresholds()[best])
    matches_none = bool(distances[best] > threshold)
    name = classifier.candidate_names_[best]
    verdict = (
        f"matches none of the candidates: nearest is {name!r} at distance "
        f"{distances[best]:.4g}, beyond {threshold:.4g} seen in training"
        if matches_none
        else f"{name}"
    )
    # The physics baseline's view of the same telemetry: the inertia tensor the
    # integral-form least squares estimates from it, whatever the classifier's kind.
    estimate = estimate_inertia(scenario, sequence, series)
    tensor = np.asarray(estimate.inertia_kg_m2)
    finite = bool(np.all(np.isfinite(tensor)))
    condition = float(estimate.condition_number)
    return Identification(
        candidate_index=best,
        candidate=name,
        inertia_kg_m2=scenario.inertia_candidates[best].inertia_kg_m2,
        distances={
            n: float(d) for n, d in zip(classifier.candidate_names_, distances, strict=True)
        },
        margin=margin,
        relative_margin=margin / runner_up if runner_up > 0 else 0.0,
        threshold=threshold,
        matches_none=matches_none,
        verdict=verdict,
        estimated_inertia_kg_m2=tensor.tolist() if finite else None,
        estimated_principal_moments_kg_m2=np.linalg.eigvalsh(tensor).tolist() if finite else None,
        estimate_condition_number=condition if np.isfinite(condition) else None,
        poorly_excited=estimate.poorly_excited(),
    )
