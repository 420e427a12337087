"""A job's headline numbers: the few figures a list of runs shows, sorts and compares.

Each job type names its summary columns once, here (:data:`SUMMARY_COLUMNS`); the store
writes ``summarise(type, result)`` into ``jobs.summary`` when a job finishes, the API
sorts by those keys and serves the column list in ``GET /vocabulary``, and the
dashboard draws one table column per entry. A new headline figure is one
:class:`SummaryColumn` and one line in the type's function below.

Pure: result dictionaries (as the worker stores them) in, flat ``{key: float | None}``
out. A result missing a part gives None for the figures drawn from it, never an error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from typing import Any, Literal

__all__ = ["SUMMARY_COLUMNS", "SummaryColumn", "columns_for", "summarise", "summary_keys"]


@dataclass(frozen=True)
class SummaryColumn:
    """One headline figure of a job type.

    :param key: its name in ``jobs.summary`` and in ``GET /jobs?sort=``.
    :param label: what a person reads in a column header.
    :param unit: SI unit, or "" for a fraction or a count.
    :param better: "high" or "low": which way a comparison should look.
    :param digits: decimals a table shows a fraction with (0: a count). The dashboard
        writes a figure with a unit to three significant digits, where decimals lost them.
    """

    key: str
    label: str
    unit: str
    better: Literal["high", "low"]
    digits: int = 3

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


SUMMARY_COLUMNS: dict[str, tuple[SummaryColumn, ...]] = {
    "search": (
        SummaryColumn("fresh_f1", "fresh F1 (mean)", "", "high"),
        SummaryColumn("fresh_f1_min", "fresh F1 (min)", "", "high"),
        SummaryColumn("design_accuracy", "accuracy at the design noise", "", "high"),
        SummaryColumn("search_score", "score on the search's draw", "", "high"),
        SummaryColumn("residual_rate_rad_s", "residual rate (settled)", "rad/s", "low", 4),
        SummaryColumn("fuel_nms", "commanded impulse", "N m s", "low", 1),
        SummaryColumn("wall_time_s", "search time", "s", "low", 1),
        SummaryColumn("timesteps", "environment steps", "", "low", 0),
    ),
    "train": (
        SummaryColumn("f1", "training F1", "", "high"),
        SummaryColumn("accuracy", "training accuracy", "", "high"),
    ),
    "sweep": (
        SummaryColumn("accuracy_min", "lowest accuracy", "", "high"),
        SummaryColumn("accuracy_mean", "mean accuracy", "", "high"),
        SummaryColumn("ceiling_shortfall", "largest shortfall from the ceiling", "", "low"),
    ),
}


def columns_for(job_type: str) -> tuple[SummaryColumn, ...]:
    return SUMMARY_COLUMNS.get(job_type, ())


def summary_keys() -> tuple[str, ...]:
    """Every summary key of every job type (a key means the same in each type using it)."""
    return tuple(dict.fromkeys(c.key for cols in SUMMARY_COLUMNS.values() for c in cols))


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _get(data: Any, *path: str) -> Any:
    for part in path:
        if not isinstance(data, Mapping):
            return None
        data = data.get(part)
    return data


def _design_accuracy(front: Mapping[str, Any]) -> float | None:
    """The best sequence's measured accuracy at the design noise, where no choice biased
    it: the confirmation of a front chosen among several sequences, or the measurement of
    the one sequence another method found; None otherwise (predicted, or cancelled before
    the confirmation)."""
    if front.get("accuracy_source") != "measured":
        return None
    confirmed = _number(_get(front, "confirmation", "accuracy"))
    if confirmed is not None or front.get("candidates_rescored") != 1:
        return confirmed
    members = front.get("members") or []
    return _number(_get(members[0], "scores", "accuracy")) if members else None


def _search(result: Mapping[str, Any]) -> dict[str, float | None]:
    front = result.get("front")
    front = front if isinstance(front, Mapping) else {}
    members = front.get("members")
    best = members[0] if isinstance(members, list) and members else {}
    # The residual rate the front and the plans give, the best sequence's once the
    # actuation lag has delivered its torque (mean over candidates, on a fresh draw), not
    # the rate when its last command ends; None for a result without a front.
    residual = _number(_get(best, "scores", "final_rate_rad_s"))
    return {
        "fresh_f1": _number(_get(result, "fresh", "f1_mean")),
        "fresh_f1_min": _number(_get(result, "fresh", "f1_min")),
        "design_accuracy": _design_accuracy(front),
        "search_score": _number(_get(result, "best", "f1")),
        "residual_rate_rad_s": residual,
        "fuel_nms": _number(_get(result, "best", "fuel_nms")),
        "wall_time_s": _number(result.get("wall_time_s")),
        "timesteps": _number(result.get("timesteps")),
    }


def _train(result: Mapping[str, Any]) -> dict[str, float | None]:
    return {"f1": _number(result.get("f1")), "accuracy": _number(result.get("accuracy"))}


def _sweep(result: Mapping[str, Any]) -> dict[str, float | None]:
    points = [p for p in result.get("points") or [] if isinstance(p, Mapping)]
    accuracies = [a for a in (_number(p.get("accuracy")) for p in points) if a is not None]
    # Results from before the ceiling hold only the old reference line, named limit,
    # which a classifier could beat: it is no ceiling, so no shortfall is claimed from it.
    ceiling = {
        (p.get("noise"), p.get("multiple")): _number(p.get("accuracy"))
        for p in result.get("ceiling") or []
        if isinstance(p, Mapping)
    }
    shortfalls = []
    for p in points:
        bound = ceiling.get((p.get("noise"), p.get("multiple")))
        accuracy = _number(p.get("accuracy"))
        if bound is not None and accuracy is not None:
            shortfalls.append(bound - accuracy)
    return {
        "accuracy_min": min(accuracies) if accuracies else None,
        "accuracy_mean": sum(accuracies) / len(accuracies) if accuracies else None,
        "ceiling_shortfall": max(shortfalls) if shortfalls else None,
    }


_SUMMARISERS: dict[str, Callable[[Mapping[str, Any]], dict[str, float | None]]] = {
    "search": _search,
    "train": _train,
    "sweep": _sweep,
}


def summarise(job_type: str, result: Mapping[str, Any] | None) -> dict[str, float | None] | None:
    """The headline figures of a job's result, by :data:`SUMMARY_COLUMNS` key; None
    without a result."""
    if not isinstance(result, Mapping):
        return None
    summarise_type = _SUMMARISERS.get(job_type)
    if summarise_type is None:
        return {}
    figures = summarise_type(result)
    return {c.key: figures.get(c.key) for c in columns_for(job_type)}
