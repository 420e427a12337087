"""Results as tables: what a CSV download of a job's result (or a verdict) holds.

Each job type names its tables once, here (:data:`RESULT_TABLES`, served in ``GET
/vocabulary``); ``GET /jobs/{id}/result?format=csv&table=NAME`` writes one of them
(``format=json``: its rows as objects, :func:`to_records`) and the dashboard's download
buttons list them. A new table is one function and one entry.

Pure: result dictionaries (as the worker stores them) in, :class:`Table` out. Thrusters
and steps are numbered from 1, as on the dashboard and in the report.
"""

from __future__ import annotations

import io
import itertools
import math
import operator
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from inertia_id.checks import spreadsheet_safe, spreadsheet_safe_json
from inertia_id.errors import InputError

__all__ = [
    "FEASIBLE_METRIC",
    "RESULT_TABLES",
    "SEARCH_METRICS",
    "Table",
    "identify_table",
    "job_notes",
    "job_status_notes",
    "metric_keys",
    "metrics_notes",
    "metrics_table",
    "metrics_with_degrees",
    "note_lines",
    "plan_notes",
    "result_table",
    "to_csv",
    "to_records",
]


@dataclass(frozen=True)
class Table:
    """A header and rows of cells (numbers, text, or None for an empty cell), and notes:
    figures about the whole table, which the CSV writes as ``# name: value`` lines before
    the header, as the command plan's CSV does (``pandas.read_csv(path, comment="#")``
    skips them); a name carries its unit (``_rad_s``, ``_kg_m2``)."""

    header: Sequence[str]
    rows: Sequence[Sequence[Any]]
    notes: Sequence[tuple[str, Any]] = ()


def _cell(value: Any) -> Any:
    """A value as a cell: names (the user's text) as a spreadsheet shows them as text,
    lists and objects as JSON that reads back exactly."""
    if value is None:
        return ""
    if isinstance(value, list | tuple | dict):
        return spreadsheet_safe_json(value)
    if isinstance(value, float):
        return repr(value)  # shortest text that reads back as the same float
    return spreadsheet_safe(value) if isinstance(value, str) else value


def _note(value: Any) -> str:
    """A note's value on one line: lists and objects as JSON, floats as they read back."""
    return " ".join(str(_cell(value)).splitlines())


def _field(value: Any) -> str:
    """One CSV field: RFC 4180 quoting, and a ``#`` quoted too.

    Written here, not by :mod:`csv`: its minimal quoting never quotes ``#``, and a reader
    told that ``#`` starts a comment (``pandas.read_csv(path, comment="#")``, as these
    files are read for their notes) cut an unquoted candidate name such as ``config #2``
    there and shifted the rest of its row.
    """
    text = str(value)
    if any(c in text for c in ',"\r\n#') or text != text.strip():
        return '"' + text.replace('"', '""') + '"'
    return text


def _line(values: Sequence[Any]) -> str:
    fields = [_field(_cell(v)) for v in values]
    if fields == [""]:
        fields = ['""']  # a lone empty field, not a blank line that readers skip
    return ",".join(fields) + "\n"


def note_lines(notes: Sequence[tuple[str, Any]]) -> str:
    """``# name: value`` lines, each value on one line (as a table's notes)."""
    return "".join(f"# {name}: {_note(value)}\n" for name, value in notes)


def to_csv(table: Table) -> str:
    """The table as CSV text (RFC 4180 quoting, a ``#`` in a field quoted as well, ``\\n``
    line ends), its notes first."""
    out = io.StringIO()
    out.write(note_lines(table.notes))
    out.write(_line(table.header))  # headers can hold names
    for row in table.rows:
        out.write(_line(row))
    return out.getvalue()


def iso_utc(value: datetime | None) -> str | None:
    """A stored time as ISO 8601 in UTC with ``Z`` (SQLite hands back naive datetimes;
    every stored time is UTC), as the job's JSON writes it."""
    if value is None:
        return None
    utc = value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)
    return utc.isoformat().replace("+00:00", "Z")


def job_notes(job: Mapping[str, Any], exported_at: datetime) -> list[tuple[str, Any]]:
    """The ``#`` lines every CSV of a job begins with, so that a file handed on (or
    renamed) still says which job it comes from and when it was written: the job's id,
    type, scenario and seed, when it was created and finished, and when it was exported.

    :param job: the job's ``id``, ``type``, ``scenario_id``, ``seed``, ``created_at`` and
        ``finished_at`` (datetimes; a missing one is an empty note).
    """
    return [
        ("job_id", job.get("id")),
        ("job_type", job.get("type")),
        ("scenario_id", job.get("scenario_id")),
        ("job_seed", job.get("seed")),
        ("created_at", iso_utc(job.get("created_at"))),
        ("finished_at", iso_utc(job.get("finished_at"))),
        ("exported_at", iso_utc(exported_at)),
    ]


def job_status_notes(job: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """A ``job_status`` line after :func:`job_notes` for a job that did not succeed (a
    cancelled one keeps what it had made before it stopped), as a cancelled search's
    plan says it; none for a succeeded job or one whose status is not given."""
    status = job.get("status")
    return [] if status in (None, "succeeded") else [("job_status", status)]


def plan_notes(
    source: Mapping[str, Any], job: Mapping[str, Any] | None, exported_at: datetime
) -> list[tuple[str, Any]]:
    """The ``#`` lines a command plan's CSV begins with, before the plan's own: for a
    plan of a job's sequence the lines every CSV of the job begins with
    (:func:`job_notes`), then the rest of where it comes from (the front member, a
    cancelled search's status); for any other, where it comes from (the scenario's id)
    and when it was exported.

    :param source: where the sequence comes from, as the plan's JSON states it.
    :param job: the job it comes from (what :func:`job_notes` reads), or None.
    """
    if job is None:
        return [*source.items(), ("exported_at", iso_utc(exported_at))]
    head = job_notes(job, exported_at)
    named = {name for name, _value in head}
    return [*head, *((name, value) for name, value in source.items() if name not in named)]


def to_records(table: Table) -> list[dict[str, Any]]:
    """The table as JSON data: one object per row, keyed by the header (lists kept)."""
    return [dict(zip(table.header, row, strict=True)) for row in table.rows]


def _mean(values: Any) -> float | None:
    numbers = [v for v in values or [] if isinstance(v, int | float)]
    return sum(numbers) / len(numbers) if numbers else None


def _deg(value: Any) -> Any:
    """A rate in rad/s (a number, or lists of them) in deg/s, for the column a flight
    team reads beside each ``_rad_s`` one; None (an empty cell) stays None."""
    if isinstance(value, bool) or value is None:
        return None
    if isinstance(value, int | float):
        return math.degrees(value)
    if isinstance(value, list | tuple):
        return [_deg(v) for v in value]
    return None


def _with_degrees(pairs: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
    """Each ``…_rad_s…`` quantity followed by its ``…_deg_s…`` twin (a flight team reads
    deg/s; the rad/s name is kept as clients read it)."""
    out: list[tuple[str, Any]] = []
    for name, value in pairs:
        out.append((name, value))
        if "_rad_s" in name:
            out.append((name.replace("_rad_s", "_deg_s"), _deg(value)))
    return out


# Search.


def _best_label(result: Mapping[str, Any]) -> str:
    """What the best sequence's ``f1`` holds (:func:`_score_name`): NSGA-II's prediction
    (no draw made it), or the score on the search's draw."""
    score = _score_name(result)
    return f"best_{score}" if result.get("method") == "nsga2" else f"best_{score}_search_draw"


def _confirmation_rows(result: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The front's member 0 measured again on series that did not rank it first (its own
    figure there is biased up on average); none when the front holds none."""
    confirmation = (result.get("front") or {}).get("confirmation")
    if not confirmation:
        return []
    return [
        ("front_member_0_confirmed_accuracy", confirmation.get("accuracy")),
        ("front_member_0_confirmed_accuracy_by_noise", confirmation.get("accuracy_by_noise")),
        ("front_member_0_confirmed_interval_by_noise", confirmation.get("interval_by_noise")),
        ("front_member_0_confirmation_series_per_candidate", confirmation.get("test_series")),
        # The baselines that could dominate member 0, measured on the same series (whether
        # one does is judged there).
        *(
            row
            for name, figures in (confirmation.get("baselines") or {}).items()
            for row in (
                (
                    f"front_member_0_confirmation_{name}_accuracy_by_noise",
                    figures.get("accuracy_by_noise"),
                ),
                (
                    f"front_member_0_confirmation_{name}_dominates_member_0",
                    figures.get("dominates_member_0"),
                ),
            )
        ),
    ]


def _search_summary(result: Mapping[str, Any]) -> Table:
    best = result.get("best") or {}
    fresh = result.get("fresh") or {}
    objective = (result.get("settings") or {}).get("scorer", {}).get("objective", "f1")
    pairs = _with_degrees(
        [
            ("method", result.get("method")),
            # NSGA-II ranks by the operator's objectives, not the scorer's: its F1 setting
            # only scores the best sequence's fresh draws (the fresh_f1 rows).
            ("objective", "operator objectives" if result.get("method") == "nsga2" else objective),
            ("best_sequence", best.get("sequence")),
            (_best_label(result), best.get("f1")),
            *_best_rate_rows(result.get("method"), best),
            # The JSON's fuel_nms: commanded angular impulse, not propellant (a mass).
            ("impulse_nms", best.get("fuel_nms")),
            *_constraint_rows(result),
            *_taken_off_rows(result),
            *_confirmation_rows(result),
            ("fresh_f1_mean", fresh.get("f1_mean")),
            ("fresh_f1_min", fresh.get("f1_min")),
            ("fresh_draws", len(fresh.get("f1") or [])),
            ("fresh_end_rate_rad_s_mean", _mean(fresh.get("final_rate_rad_s"))),
            ("timesteps", result.get("timesteps")),
            ("episodes", result.get("episodes")),
            ("wall_time_s", result.get("wall_time_s")),
            ("stopped", result.get("stopped")),
            ("space_size", result.get("space_size")),
        ]
    )
    return Table(["quantity", "value"], [list(p) for p in pairs])


def _constraint_rows(result: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """Whether the best met the search's constraints on its draw: a search other than
    NSGA-II keeps its best when no sequence it tried met them (the least violating), and
    the summary said nothing of it while the front, judged on fresh draws, could say
    "within the constraints". None without constraints."""
    if not (result.get("settings") or {}).get("constraints"):
        return []
    violation = (result.get("best") or {}).get("constraint_violation")
    if violation is None:
        return []
    return [
        ("best_meets_constraints_search_draw", violation <= 0),
        ("best_constraint_violation_search_draw", violation),
    ]


def _taken_off_rows(result: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The sequence the search found and the impulse taken off it, where its cancelling
    firings were taken off after the search."""
    taken = result.get("firings_taken_off")
    if not isinstance(taken, Mapping):
        return []
    return [
        ("sequence_found", taken.get("sequence_found")),
        ("impulse_found_nms", taken.get("impulse_found_nms")),
        ("impulse_saved_nms", taken.get("impulse_saved_nms")),
    ]


def _best_rate_rows(method: Any, best: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """The best sequence's rates on the search's draw, each named for what it is: the
    residual rate once the lag is empty (the job summary's residual_rate, every method),
    and, for the searches that measure it, |ω| when the last command ends (the plan's
    end_rate, the paper's reward; the fresh figure below is that one too)."""
    if method == "nsga2":
        # NSGA-II's final_rate_rad_s has always been the operator scorer's settled rate.
        residual = best.get("residual_rate_rad_s", best.get("final_rate_rad_s"))
        return [("best_residual_rate_rad_s_search_draw", residual)]
    return [
        ("best_end_rate_rad_s_search_draw", best.get("final_rate_rad_s")),
        # None in results stored before the searches recorded it.
        ("best_residual_rate_rad_s_search_draw", best.get("residual_rate_rad_s")),
    ]


_CURVE = ("timesteps", "episodes", "mean_episode_reward", "mean_f1", "best_f1")


def _score_name(result: Mapping[str, Any]) -> str:
    """What a curve's ``mean_f1``/``best_f1`` hold, as the CSV names them
    (:func:`~inertia_id.search.records.score_name`)."""
    from inertia_id.search.records import score_name  # the search package loads on use

    objective = (result.get("settings") or {}).get("scorer", {}).get("objective", "f1")
    return score_name(result.get("method"), objective)


def _search_curve(result: Mapping[str, Any]) -> Table:
    curve = [p for p in result.get("curve") or [] if isinstance(p, Mapping)]
    score = _score_name(result)
    # The stored points name the objective's score f1 whatever it is; the columns say.
    columns = [*_CURVE[:3], f"mean_{score}", f"best_{score}"]
    key, old = "best_residual_rate_rad_s", "best_final_rate_rad_s"
    if curve and all(key not in p for p in curve) and any(old in p for p in curve):
        # Stored before the key was named for what it is: NSGA-II's was its residual
        # rate already; the other searches' was |ω| when the last command ends.
        name = key if result.get("method") == "nsga2" else "best_end_rate_rad_s"
        return Table(
            [*columns, name, name.replace("_rad_s", "_deg_s")],
            [[*(p.get(k) for k in _CURVE), p.get(old), _deg(p.get(old))] for p in curve],
        )
    feasible = "best_feasible"
    if any(feasible in p for p in curve):
        # Stored since the curve says whether its best met the constraints.
        return Table(
            [*columns, key, key.replace("_rad_s", "_deg_s"), feasible],
            [
                [*(p.get(k) for k in (*_CURVE, key)), _deg(p.get(key)), p.get(feasible)]
                for p in curve
            ],
        )
    return Table(
        [*columns, key, key.replace("_rad_s", "_deg_s")],
        [[*(p.get(k) for k in (*_CURVE, key)), _deg(p.get(key))] for p in curve],
    )


def _sequence_rows(sequence: Any) -> Table:
    steps = [list(row) for row in sequence or []]
    n = max((len(r) for r in steps), default=0)
    header = ["step", *(f"thruster_{j + 1}_level" for j in range(n))]
    return Table(header, [[i + 1, *row] for i, row in enumerate(steps)])


def _search_sequence(result: Mapping[str, Any]) -> Table:
    return _sequence_rows((result.get("best") or {}).get("sequence"))


def _search_baselines(result: Mapping[str, Any]) -> Table:
    best = result.get("best") or {}
    fresh = result.get("fresh") or {}
    rows = [
        [
            "found by the search",
            fresh.get("f1_mean"),
            fresh.get("f1_min"),
            _mean(fresh.get("final_rate_rad_s")),
            _deg(_mean(fresh.get("final_rate_rad_s"))),
            best.get("fuel_nms"),
            best.get("sequence"),
            None,
        ]
    ]
    for name, base in (result.get("baselines") or {}).items():
        f1 = base.get("fresh_f1") or []
        rows.append(
            [
                name,
                _mean(f1),
                min(f1) if f1 else None,
                _mean(base.get("fresh_final_rate_rad_s")),
                _deg(_mean(base.get("fresh_final_rate_rad_s"))),
                base.get("fuel_nms"),
                base.get("sequence"),
                base.get("unavailable"),  # why a baseline has no figures (e.g. too short)
            ]
        )
    header = [
        "sequence",
        "fresh_f1_mean",
        "fresh_f1_min",
        "fresh_end_rate_rad_s_mean",
        "fresh_end_rate_deg_s_mean",
        "impulse_nms",
        "levels",
        "unavailable",
    ]
    return Table(header, rows)


_FRONT_FIGURES = (
    "accuracy",
    "final_rate_rad_s",
    "final_rate_deg_s",
    # What a residual-rate bound is held to: the candidate that ends fastest.
    "final_rate_max_rad_s",
    "final_rate_max_deg_s",
    # What a per-flight bound is held to: the rate 95 % of that candidate's flights stay
    # under (empty for a front stored before it).
    "final_rate_p95_rad_s",
    "final_rate_p95_deg_s",
    "peak_rate_rad_s",
    "peak_rate_deg_s",
    # The same per-flight bound on each flight's own peak (empty before it was stored).
    "peak_rate_p95_rad_s",
    "peak_rate_p95_deg_s",
    "impulse_nms",
    "on_time_s",
    "propellant_kg",
    "duration_s",
    "attitude_change_deg",
)


#: The part of the residual the sequence itself leaves (the plan's prediction from rest),
#: mean and worst candidate: beside an initial-rate spread the final_rate figures carry
#: |ω(0)|, which no sequence removes (empty for a front stored before it). Last in the
#: front's table, after ``sequence``: a reader that takes the columns by position keeps
#: every earlier column where it was (inserted after final_rate_deg_s, they moved every
#: column from final_rate_max_rad_s on four places right).
_FRONT_COMMANDED = (
    "commanded_residual_rate_rad_s",
    "commanded_residual_rate_deg_s",
    "commanded_residual_rate_max_rad_s",
    "commanded_residual_rate_max_deg_s",
)


def _predicted(scores: Mapping[str, Any]) -> float | None:
    """The mean predicted accuracy beside a measured one (None when it was predicted)."""
    values = scores.get("predicted_accuracy_by_noise")
    return None if not values else float(sum(values) / len(values))


def _condition_names(front: Mapping[str, Any]) -> list[str]:
    """A column suffix per design condition, e.g. ``6x_process_1x_gyro``."""
    out = []
    for pair in front.get("design_noise") or []:
        try:
            process, gyro = (float(v) for v in pair)
        except (TypeError, ValueError):
            return []
        out.append(f"{process:g}x_process_{gyro:g}x_gyro")
    return out


def _by_condition(scores: Mapping[str, Any], conditions: list[str]) -> list[Any]:
    """The accuracy at each design condition, then the prediction at each (blank where
    the accuracy was predicted, as the mean column)."""
    out: list[Any] = []
    for key in ("accuracy_by_noise", "predicted_accuracy_by_noise"):
        values = scores.get(key)
        values = values if isinstance(values, list) and len(values) == len(conditions) else []
        out += values or [None] * len(conditions)
    return out


def _front_figures(scores: Mapping[str, Any], keys: Sequence[str] = _FRONT_FIGURES) -> list[Any]:
    """A member's or baseline's figures; a deg/s one a front stored without it (only
    its rad/s twin) converted from that twin, not left empty."""
    out = []
    for key in keys:
        value = scores.get(key)
        if value is None and key.endswith("_deg_s"):
            value = _deg(scores.get(key.replace("_deg_s", "_rad_s")))
        out.append(value)
    return out


def _search_front(result: Mapping[str, Any]) -> Table:
    """The front's members, then the baselines, on the same fresh draws: one row each;
    ``accuracy_source`` says whether ``accuracy`` was measured or predicted; the accuracy
    (and the prediction) at each design condition beside the mean."""
    front = result.get("front") or {}
    source = front.get("accuracy_source", "predicted")
    conditions = _condition_names(front)
    rows: list[list[Any]] = []
    for member in front.get("members") or []:
        scores = member.get("scores") or {}
        rows.append(
            [
                "member",
                member.get("index"),
                *_front_figures(scores),
                source,
                _predicted(scores),
                *_by_condition(scores, conditions),
                member.get("feasible"),
                list(member.get("dominated_by") or []),
                [],
                member.get("sequence"),
                *_front_figures(scores, _FRONT_COMMANDED),
                member.get("fires"),
            ]
        )
    for name, base in (front.get("baselines") or {}).items():
        if "unavailable" in base:
            continue
        scores = base.get("scores") or {}
        rows.append(
            [
                "baseline",
                name,
                *_front_figures(scores),
                source,
                _predicted(scores),
                *_by_condition(scores, conditions),
                base.get("feasible"),
                [],
                list(base.get("dominates") or []),
                base.get("sequence"),
                *_front_figures(scores, _FRONT_COMMANDED),
                base.get("fires"),
            ]
        )
    header = [
        "kind",
        "member",
        *_FRONT_FIGURES,
        "accuracy_source",
        "predicted_accuracy",
        *(f"accuracy_{c}" for c in conditions),
        *(f"predicted_accuracy_{c}" for c in conditions),
        "feasible",
        "dominated_by",
        "dominates_members",
        "sequence",
        *_FRONT_COMMANDED,
        # False: it applies no torque, no classifier trains on it (empty for a front
        # stored before it said so). Last, as the commanded figures were added.
        "fires",
    ]
    return Table(header, rows)


# Train.


def _confusion(names: Sequence[str], confusion: Any) -> Table:
    header = ["true \\ predicted", *names]
    return Table(header, [[names[i], *row] for i, row in enumerate(confusion or [])])


def _train_summary(result: Mapping[str, Any]) -> Table:
    keys = ("classifier_id", "kind", "metric", "f1", "accuracy", "n_realisations", "sequence")
    return Table(["quantity", "value"], [[k, result.get(k)] for k in keys])


def _train_confusion(result: Mapping[str, Any]) -> Table:
    return _confusion(result.get("candidate_names") or [], result.get("confusion"))


def _train_sequence(result: Mapping[str, Any]) -> Table:
    return _sequence_rows(result.get("sequence"))


# Sweep.

_POINT = ("noise", "multiple", "value", "accuracy", "ci_low", "ci_high", "f1", "n_series")


def _sweep_lines(result: Mapping[str, Any]) -> list[tuple[str, list[Mapping[str, Any]]]]:
    lines = [("classifier", list(result.get("points") or []))]
    lines += [
        (f"other:{name}", list(points)) for name, points in (result.get("others") or {}).items()
    ]
    if result.get("ceiling"):
        lines.append(("ceiling", list(result["ceiling"])))
    elif result.get("limit"):
        # A result from before the ceiling: its reference line, which is no ceiling.
        lines.append(("reference (not a ceiling)", list(result["limit"])))
    return lines


def _above_ceiling(
    who: str, point: Mapping[str, Any], ceiling: Mapping[tuple[Any, Any], Mapping[str, Any]]
) -> bool | None:
    """Whether the point's accuracy lies above the ceiling's interval at the same point:
    as the sweep stated it, or, in a result stored before it did, from the intervals."""
    if who == "ceiling" or who.startswith("reference"):
        return None
    if "above_ceiling_interval" in point:
        return point["above_ceiling_interval"]
    top = ceiling.get((point.get("noise"), point.get("multiple")))
    if top is None or not isinstance(point.get("accuracy"), int | float):
        return None
    return bool(point["accuracy"] > top.get("ci_high", 1.0))


def _sweep_points(result: Mapping[str, Any]) -> Table:
    """One row per classifier, noise and multiple; ``step`` is the multiple's index, as
    the job's metrics number their points."""
    units = result.get("units") or {}
    ceiling = {(p.get("noise"), p.get("multiple")): p for p in result.get("ceiling") or []}
    rows = []
    for who, points in _sweep_lines(result):
        steps: dict[Any, int] = {}
        for p in points:
            step = steps[p.get("noise")] = steps.get(p.get("noise"), -1) + 1
            rows.append(
                [
                    who,
                    *(p.get(k) for k in _POINT[:2]),
                    step,
                    *(p.get(k) for k in _POINT[2:]),
                    units.get(p.get("noise"), ""),
                    # The level in deg/s where it is a rate (gyro noise and bias).
                    _deg(p.get("value")) if units.get(p.get("noise")) == "rad/s" else None,
                    _above_ceiling(who, p, ceiling),
                ]
            )
    header = [
        "who",
        *_POINT[:2],
        "step",
        *_POINT[2:],
        "value_unit",
        "value_deg_s",
        "above_ceiling_interval",
    ]
    return Table(header, rows)


def _sweep_confusion(result: Mapping[str, Any]) -> Table:
    names = result.get("candidate_names") or []
    rows = []
    for who, points in _sweep_lines(result):
        for p in points:
            for i, row in enumerate(p.get("confusion") or []):
                for j, count in enumerate(row):
                    rows.append([who, p.get("noise"), p.get("multiple"), names[i], names[j], count])
    return Table(["who", "noise", "multiple", "true", "predicted", "count"], rows)


def _sweep_inertia(result: Mapping[str, Any]) -> Table:
    """One row per body off the candidates: what it is (the candidate scaled, ``base``,
    or the pair it lies between), how often it was flagged, and the candidate each of its
    series was nearest to."""
    inertia = result.get("inertia") or {}
    names = list(inertia.get("candidate_names") or result.get("candidate_names") or [])

    def name(index: Any) -> Any:
        return names[index] if isinstance(index, int) and 0 <= index < len(names) else index

    base = name(inertia.get("base"))
    pair = [name(i) for i in inertia.get("pair") or []]
    meaning = {
        "scaled": f"multiple of {base}'s inertia tensor (1: the candidate itself)",
        "between": (
            f"position from {pair[0]} (0) to {pair[1]} (1), (1 - t) I_0 + t I_1"
            if len(pair) == 2
            else "position between the pair (0 to 1)"
        ),
    }
    rows = []
    for p in (p for p in inertia.get("points") or [] if isinstance(p, Mapping)):
        body = p.get("body")
        counts = list(p.get("predicted") or [])
        counts += [None] * (len(names) - len(counts))
        rows.append(
            [
                body,
                p.get("parameter"),
                meaning.get(str(body), ""),
                base if body == "scaled" else None,
                pair if body == "between" else None,
                p.get("n_series"),
                p.get("matches_none_rate"),
                p.get("ci_low"),
                p.get("ci_high"),
                p.get("identified_right_rate"),
                p.get("identified_wrong_rate"),
                p.get("ambiguous_rate"),
                *counts[: len(names)],
                p.get("inertia_kg_m2"),
            ]
        )
    header = [
        "body",
        "parameter",
        "parameter_meaning",
        "base",
        "pair",
        "n_series",
        "matches_none_rate",
        "ci_low",
        "ci_high",
        "identified_right_rate",
        "identified_wrong_rate",
        "ambiguous_rate",
        *(f"predicted_{n}" for n in names),
        "inertia_kg_m2",
    ]
    confidence = inertia.get("required_confidence")
    # A result stored before the sweep counted identify's verdicts has no confidence:
    # its rate is the novelty threshold's alone, and its predicted the nearest candidate.
    verdicts = confidence is not None
    notes = [
        ("inertia_seed", inertia.get("seed")),
        ("noise", "every source at 1x, the scenario's own"),
        (
            "matches_none_rate",
            f"identify's verdict matches-none or not-this-sequence (confidence {confidence:g})"
            if verdicts
            else "beyond the nearest candidate's novelty threshold (stored before the sweep "
            "counted identify's verdicts)",
        ),
        (
            "predicted",
            "predicted_<candidate>: how many of the body's series had it most probable"
            if verdicts
            else "predicted_<candidate>: how many of the body's series were nearest to it",
        ),
    ]
    return Table(header, rows, notes)


def _sweep_notes(result: Mapping[str, Any], job: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """What every table of a sweep carries as ``#`` lines: what was swept and how."""
    params = job.get("params") or {}
    ceiling = result.get("ceiling_realisations", result.get("limit_realisations"))
    return [
        *_sweep_points_missing(result, job),
        ("classifier_id", params.get("classifier_id")),
        ("test_series_seed", result.get("seed")),
        ("sequence", result.get("sequence")),
        ("metric", result.get("metric")),
        ("candidate_names", result.get("candidate_names")),
        ("n_test_per_candidate", result.get("n_test_per_candidate")),
        ("ceiling_realisations", ceiling),
        ("multiples", params.get("multiples")),
        ("levels_1x", result.get("levels")),
        ("units", result.get("units")),
        (
            "step",
            "the multiple's index among multiples (0, 1, ...): the step of the job's "
            "accuracy_<noise> metrics",
        ),
        (
            "above_ceiling_interval",
            "the accuracy lies above the upper end of the ceiling's 95 % Wilson interval "
            "at the same point (a check against that interval, not a paired test); empty "
            "for the ceiling itself and without one",
        ),
    ]


def _sweep_points_missing(
    result: Mapping[str, Any], job: Mapping[str, Any]
) -> list[tuple[str, Any]]:
    """A ``points_measured`` line when the sweep stopped before it measured every point
    it was asked for (cancelled, or at its time limit): its tables then hold the points
    measured before, and ``multiples`` lists more than they cover."""
    params = job.get("params") or {}
    asked = len(params.get("multiples") or []) * len(params.get("noises") or [])
    measured = len(result.get("points") or [])
    if not asked or measured >= asked:
        return []
    if result.get("stopped") == "time_limit":
        why = "it reached its time limit"
    elif job.get("status") == "cancelled":
        why = "it was cancelled"
    else:
        why = "it stopped"
    return [
        (
            "points_measured",
            f"{measured} of the {asked} asked for (noises x multiples): {why} before the "
            "rest; the tables hold the points measured before",
        )
    ]


def _search_notes(result: Mapping[str, Any], job: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """What every table of a search carries as ``#`` lines: how it was asked for, so that
    a front's ``feasible`` column can be read against its constraints and a table handed
    on says how it was made (:func:`job_notes` says which job it is)."""
    params = job.get("params") or {}
    names = (
        "method",
        "sequence_length",
        "objective",
        "objectives",
        "design_noise",
        "constraints",
        "n_realisations",
        "fresh_realisations",
        "fresh_test_series",
    )
    notes = [(name, params.get(name)) for name in names if name in params]
    if params.get("method") == "nsga2":
        # NSGA-II ranks by the operator's objectives (the next line), never by the
        # scorer's objective, whose default (f1) the params keep: "objective: f1" above a
        # front read as though the front were ranked by an F1 (the summary's row says
        # "operator objectives" too).
        notes = [(n, "operator objectives" if n == "objective" else v) for n, v in notes]
    return notes


#: Every job type's tables, first the default: name -> (what it holds, how it is made).
RESULT_TABLES: dict[str, dict[str, tuple[str, Callable[[Mapping[str, Any]], Table]]]] = {
    "search": {
        "summary": ("best sequence, its scores, impulse and the search's cost", _search_summary),
        "curve": ("the learning curve, one row per point", _search_curve),
        "sequence": ("the best sequence, one row per step, a level per thruster", _search_sequence),
        "baselines": (
            "the best sequence beside the baselines, same fresh draws",
            _search_baselines,
        ),
        "front": (
            "the front's members (index, fresh scores, rates in rad/s and deg/s, attitude "
            "change) and the baselines on the same fresh draw",
            _search_front,
        ),
    },
    "train": {
        "summary": ("kind, metric, training F1 and accuracy", _train_summary),
        "confusion": ("training confusion matrix (rows true, columns predicted)", _train_confusion),
        "sequence": ("the sequence, one row per step", _train_sequence),
    },
    "sweep": {
        "points": (
            "accuracy per noise and multiple, of every classifier and the ceiling",
            _sweep_points,
        ),
        "confusion": ("confusion matrices, long form: one row per cell", _sweep_confusion),
        "inertia": ('"matches none" rate of bodies off the candidates', _sweep_inertia),
    },
}


#: The job-wide facts every table of a type carries as ``#`` lines after
#: :func:`job_notes`, from the result and the job (its ``params``).
_JOB_NOTES: dict[str, Callable[[Mapping[str, Any], Mapping[str, Any]], list[tuple[str, Any]]]] = {
    "search": _search_notes,
    "sweep": _sweep_notes,
}


def result_table(
    job_type: str,
    result: Mapping[str, Any],
    table: str | None,
    job: Mapping[str, Any] | None = None,
    exported_at: datetime | None = None,
) -> Table:
    """One table of a job's result; ``table`` None: the type's first.

    :param job: the job (``params`` and what :func:`job_notes` reads), for the notes that
        say which job it is and what was run (a sweep's classifier id); without it the
        table has only its own notes.
    :param exported_at: when the table is written (default now).
    :raises InputError: the type has no table of that name (the message lists them).
    """
    tables = RESULT_TABLES.get(job_type, {})
    name = table or next(iter(tables), None)
    if name not in tables:
        raise InputError(
            f"a {job_type} result has no table {table!r}; tables: {', '.join(tables) or 'none'}"
        )
    made = tables[name][1](result)
    if job is None:
        return made
    notes = _JOB_NOTES.get(job_type)
    return Table(
        made.header,
        made.rows,
        [
            *job_notes(job, exported_at or datetime.now(UTC)),
            *job_status_notes(job),
            *(notes(result, job) if notes is not None else []),
            *made.notes,
        ],
    )


def metrics_table(
    series: Sequence[tuple[str, int, float | None]], notes: Sequence[tuple[str, Any]] = ()
) -> Table:
    """Metric points in long form: key, step, value; ``notes`` say what a step is where
    it is not obvious (a sweep's)."""
    return Table(["key", "step", "value"], [list(point) for point in series], notes)


def metrics_with_degrees(
    points: Sequence[tuple[str, int, float]],
) -> list[tuple[str, int, float]]:
    """Metric points (key, step, value), ordered by key then step, with each ``…_rad_s…``
    series followed by its ``…_deg_s…`` twin, the same points converted (a search's
    ``best_residual_rate_rad_s`` then ``best_residual_rate_deg_s``), as every other rate
    of the exports has its deg/s beside it; a twin the job stored itself is not made
    again."""
    stored = {key for key, _step, _value in points}
    out: list[tuple[str, int, float]] = []
    for key, series in itertools.groupby(points, key=operator.itemgetter(0)):
        series_points = list(series)
        out += series_points
        twin = key.replace("_rad_s", "_deg_s")
        if twin != key and twin not in stored:
            out += [(twin, step, math.degrees(value)) for _key, step, value in series_points]
    return out


def metrics_notes(job_type: str, params: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """What a job type's metric step means, when it is not a count of work done (a
    sweep's step is the index of the noise multiple), and what a search's ``mean_f1`` and
    ``best_f1`` series hold: the search's score, an F1 only for the F1 objective."""
    if job_type == "search":
        from inertia_id.search.records import SCORE_NAMES, score_name

        held = SCORE_NAMES[score_name(params.get("method"), params.get("objective", "f1"))]
        return [("mean_f1 and best_f1", held)]
    if job_type != "sweep":
        return []
    return [
        ("multiples", params.get("multiples")),
        (
            "step",
            "the multiple's index among multiples (0, 1, ...); the sweep's points table "
            "pairs each step with its multiple",
        ),
    ]


#: The metric keys a search writes after every rollout (PPO) or report (random,
#: exhaustive), at step = environment steps so far (worker.handlers.run_search_job).
SEARCH_METRICS = ("mean_episode_reward", "mean_f1", "best_f1", "best_residual_rate_rad_s")
#: Written beside them by a search with constraints: 1 where the best so far meets
#: them, 0 while none has (its best is then the most accurate of all), so the live
#: curve can say which its points are.
FEASIBLE_METRIC = "best_feasible"
#: What a training writes once, at its end (worker.handlers.run_train_job).
TRAIN_METRICS = ("f1", "accuracy")


def metric_keys(job_type: str, params: Mapping[str, Any]) -> list[str] | None:
    """The metric series a job of ``job_type`` with ``params`` can record, each rad/s
    one followed by its deg/s twin (:func:`metrics_with_degrees`): a search's
    :data:`SEARCH_METRICS` (and :data:`FEASIBLE_METRIC` with constraints), a training's
    :data:`TRAIN_METRICS`, a sweep's ``accuracy_<noise>`` for each noise it sweeps
    (worker.handlers.run_sweep_job). None for a type whose series are not known here."""
    if job_type == "search":
        keys = [*SEARCH_METRICS, *([FEASIBLE_METRIC] if params.get("constraints") else [])]
    elif job_type == "train":
        keys = list(TRAIN_METRICS)
    elif job_type == "sweep":
        from inertia_id.evaluation.sweep import DEFAULT_NOISES

        keys = [f"accuracy_{noise}" for noise in params.get("noises") or DEFAULT_NOISES]
    else:
        return None
    twins = {key: key.replace("_rad_s", "_deg_s") for key in keys}
    return [name for key in keys for name in dict.fromkeys((key, twins[key]))]


#: What the identify CSV's figures are measured in.
_IDENTIFY_UNITS = (
    "posterior, p_none, confidence and required_confidence are probabilities in [0, 1] "
    "(the posteriors and p_none sum to 1); distance, threshold and margin are the "
    "classifier's own distance to a candidate (compare them with each other, not across "
    "kinds); rates in rad/s (_rad_s) and deg/s (_deg_s), inertia in kg m^2; "
    "sequence_start and the stamps in the telemetry's clock (seconds) or ISO-8601 UTC, "
    "shifts, telemetry_span_s and the "
    "telemetry_gaps (from_s, to_s, length_s) in s from the start used; "
    "sequence_covered_fraction the part of the sequence's grid times outside those gaps, "
    "sequence_measured_fraction the part with a real sample within half a grid period; "
    "off_candidates_log_bayes a natural-log Bayes factor of another body near the "
    "candidates against them (a candidate is named only below 0; empty for a kind without "
    "that model), fits_off_candidates whether it withheld the name (empty where the "
    "classifier cannot test for other bodies: off_candidates_note then says so)"
)


def identify_table(verdict: Mapping[str, Any]) -> Table:
    """A verdict, one row per candidate: its posterior, its distance and whether it is
    the verdict's candidate (the most probable); the verdict's basis as notes: status
    and confidence against the one required, the probability of none of these, the
    novelty threshold, the offset measured before the start and the least-squares
    estimate when there are, and the units."""
    distances = verdict.get("distances") or {}
    posterior = verdict.get("posterior") or {}
    names = list(dict.fromkeys([*distances, *posterior]))
    # ``number``: the candidate's number from 1, in the classifier's order, as plan tables
    # and the verdict's candidate_number number it (appended: the columns before it keep
    # their places for readers by position).
    rows = [
        [name, distances.get(name), name == verdict.get("candidate"), posterior.get(name), k]
        for k, name in enumerate(names, start=1)
    ]
    notes: list[tuple[str, Any]] = [
        ("classifier_id", verdict.get("classifier_id")),
        ("status", verdict.get("status")),
        ("verdict", verdict.get("verdict")),
        ("candidate", verdict.get("candidate")),
        ("candidate_number", verdict.get("candidate_number")),
        ("candidate_inertia_kg_m2", verdict.get("inertia_kg_m2")),
        ("confidence", verdict.get("confidence")),
        ("required_confidence", verdict.get("required_confidence")),
        ("p_none", verdict.get("p_none")),
        ("matches_none", verdict.get("matches_none")),
        ("not_this_sequence", verdict.get("not_this_sequence")),
        ("threshold", verdict.get("threshold")),
        ("margin", verdict.get("margin")),
        ("relative_margin", verdict.get("relative_margin")),
        ("sequence_start", verdict.get("sequence_start")),
        ("sequence_start_shift_s", verdict.get("sequence_start_shift_s")),
        ("telemetry_first_stamp", verdict.get("telemetry_first_stamp")),
        ("telemetry_last_stamp", verdict.get("telemetry_last_stamp")),
        ("telemetry_samples", verdict.get("telemetry_samples")),
        ("telemetry_span_s", verdict.get("telemetry_span_s")),
        ("sequence_covered_fraction", verdict.get("sequence_covered_fraction")),
        ("sequence_measured_fraction", verdict.get("sequence_measured_fraction")),
    ]
    if verdict.get("telemetry_gaps"):
        notes.append(("telemetry_gaps", verdict.get("telemetry_gaps")))
    if verdict.get("estimate_start_within_s") is not None:
        notes += [
            ("estimate_start_within_s", verdict.get("estimate_start_within_s")),
            ("sequence_start_shifts_tried_s", verdict.get("sequence_start_shifts_tried_s")),
            ("sequence_start_refined", verdict.get("sequence_start_refined")),
        ]
    if verdict.get("start_hint") is not None:
        notes.append(("start_hint", verdict.get("start_hint")))
    if verdict.get("initial_offset_rad_s") is not None:
        notes += _with_degrees(
            [
                ("initial_offset_rad_s", verdict.get("initial_offset_rad_s")),
                ("initial_offset_std_rad_s", verdict.get("initial_offset_std_rad_s")),
            ]
        )
        notes.append(("pre_start_samples", verdict.get("pre_start_samples")))
    estimate = (
        "estimated_inertia_kg_m2",
        "estimated_principal_moments_kg_m2",
        "estimated_inertia_std_kg_m2",
        "estimate_condition_number",
        "estimate_rejected",
    )
    notes += [(key, verdict[key]) for key in estimate if verdict.get(key) is not None]
    if verdict.get("poorly_excited"):
        notes.append(("poorly_excited", verdict["poorly_excited"]))
    notes.append(("units", _IDENTIFY_UNITS))
    # Appended after the units, so that no note before them moves for a reader by position.
    notes += [
        ("fits_off_candidates", verdict.get("fits_off_candidates")),
        ("off_candidates_log_bayes", verdict.get("off_candidates_log_bayes")),
    ]
    if verdict.get("off_candidates_note"):
        notes.append(("off_candidates_note", verdict["off_candidates_note"]))
    if verdict.get("sequence_start_note"):
        notes.append(("sequence_start_note", verdict["sequence_start_note"]))
    if verdict.get("unit_hint"):
        notes.append(("unit_hint", verdict["unit_hint"]))
    if verdict.get("pre_start_hint"):
        notes.append(("pre_start_hint", verdict["pre_start_hint"]))
    if verdict.get("start_window_hint"):
        notes.append(("start_window_hint", verdict["start_window_hint"]))
    if verdict.get("pre_start_activity_hint"):
        notes.append(("pre_start_activity_hint", verdict["pre_start_activity_hint"]))
    return Table(["candidate", "distance", "nearest", "posterior", "number"], rows, notes)
