"""Gyro telemetry: time stamps from the sequence start and body rates, validated.

:class:`Telemetry` is what :func:`~inertia_id.evaluation.identify.identify` reads;
:func:`parse_telemetry` and :func:`load_telemetry` read it from JSON or CSV text, and
:func:`resample` puts it on a classifier's sample grid.
"""

from __future__ import annotations

import csv
import io
import json
import os

import numpy as np
from pydantic import BaseModel, Field, field_validator, model_validator

from ..errors import InputError

__all__ = [
    "MAX_TELEMETRY_SAMPLES",
    "Telemetry",
    "load_telemetry",
    "parse_telemetry",
    "resample",
]

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
            raise InputError(f"telemetry needs at least 2 samples, got {arr.size}")
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise InputError(f"time_s[{bad[0]}] = {value[bad[0]]!r} is not finite")
        steps = np.diff(arr)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            raise InputError(
                f"time stamps must increase strictly: time_s[{i}] = {value[i]!r}, "
                f"time_s[{i + 1}] = {value[i + 1]!r}"
            )
        return value

    @field_validator("omega_rad_s")
    @classmethod
    def _rates(cls, value: list[list[float]]) -> list[list[float]]:
        for i, row in enumerate(value):
            if len(row) != 3:
                raise InputError(f"omega_rad_s row {i} has {len(row)} columns, expected 3: {row}")
        arr = np.asarray(value, dtype=float).reshape(-1, 3)
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            i, j = (int(v) for v in bad[0])
            raise InputError(f"omega_rad_s[{i}][{j}] = {value[i][j]!r} is not finite")
        return value

    @model_validator(mode="after")
    def _lengths(self) -> Telemetry:
        if len(self.time_s) != len(self.omega_rad_s):
            raise InputError(
                f"{len(self.time_s)} time stamps but {len(self.omega_rad_s)} omega rows"
            )
        return self

    @property
    def time_array(self) -> np.ndarray:
        return np.asarray(self.time_s, dtype=float)

    @property
    def omega_array(self) -> np.ndarray:
        return np.asarray(self.omega_rad_s, dtype=float).reshape(-1, 3)


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
            raise InputError(f"telemetry is not valid JSON: {exc}") from None
        if not isinstance(data, dict):
            raise InputError("telemetry JSON must be an object with time_s and omega_rad_s")
        return Telemetry.model_validate(data)
    if fmt != "csv":
        raise InputError(f"telemetry format must be json, csv or auto, got {fmt!r}")
    try:
        rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise InputError(f"telemetry is not valid CSV: {exc}") from None
    if rows and not _numeric(rows[0][0]):
        rows = rows[1:]
    if len(rows) > MAX_TELEMETRY_SAMPLES:
        raise InputError(f"telemetry has {len(rows)} rows; at most {MAX_TELEMETRY_SAMPLES}")
    times: list[float] = []
    omegas: list[list[float]] = []
    for n, row in enumerate(rows, start=1):
        if len(row) != 4:
            raise InputError(
                f"CSV data row {n} has {len(row)} columns, expected 4 (time_s, wx, wy, wz): {row}"
            )
        try:
            values = [float(c) for c in row]
        except ValueError:
            raise InputError(f"CSV data row {n} is not numeric: {row}") from None
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
        raise InputError(
            f"telemetry spans {t[0]:.6g} s to {t[-1]:.6g} s but the sequence needs "
            f"{grid_s[0]:.6g} s to {grid_s[-1]:.6g} s (time from the sequence start)"
        )
    omega = telemetry.omega_array
    return np.stack([np.interp(grid_s, t, omega[:, axis]) for axis in range(3)], axis=-1)
