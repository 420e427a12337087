"""``inertia-id plan``: a sequence as the commands a flight team uploads."""

from __future__ import annotations

import json
import os
import re
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import click

from ..checks import MAX_SEED
from ..wording import significant
from .options import (
    OTHER_FORMATS,
    IntRange,
    friendly_errors,
    load_scenario,
    scenario_options,
    write_output,
)

if TYPE_CHECKING:
    from ..physics.scenario import Scenario

__all__ = ["plan_cmd"]


def _plan_file_name(context: click.Context, param: click.Parameter, value: str) -> str:
    """A plan named for a format other than CSV or JSON (``plan.npz``, ``plan.xlsx``) is
    refused: JSON text was written into it."""
    if value.lower().endswith(tuple(f for f in OTHER_FORMATS if f != ".csv")):
        raise click.BadParameter(
            f"plan writes CSV (to a .csv name) or JSON (to any name of no other known "
            f"format); name the file .csv or .json, got {value!r}"
        )
    return value


@click.command("plan")
@scenario_options
@click.option(
    "--sequence",
    "sequence_text",
    default=None,
    help="Level indices, rows separated by ';' (e.g. '4,4,4,0,0,0;0,0,0,4,4,4'), a JSON "
    "list of rows, or a JSON file holding one (a command plan's JSON too).",
)
@click.option(
    "--search",
    "search_path",
    type=click.Path(dir_okay=False, exists=True),
    default=None,
    help="A search JSON (from `search`): plan its front member --member (default its best) "
    "on the scenario the search ran on (recorded in the JSON).",
)
@click.option(
    "--member",
    type=IntRange(0),
    default=None,
    help="With --search: the front member's index (0 = the most accurate).",
)
@click.option(
    "--flights",
    type=IntRange(0),
    default=0,
    show_default=True,
    help="Also fly the sequence this many times a candidate at the scenario's noise and "
    "state how the residual and peak rates spread over single flights: per candidate "
    "the residual's mean, 95th percentile and largest, and for the residual and the peak "
    "a rate at least 95 % of flights stay under with 95 % confidence; at least 2, and 59 "
    "for that bound to be an order statistic; 0: the nominal prediction alone.",
)
@click.option(
    "--seed",
    type=IntRange(0, MAX_SEED),
    default=0,
    show_default=True,
    help=f"Seed of --flights (0 to {MAX_SEED}, as the service's plan takes).",
)
@click.option(
    "--out",
    default="plan.json",
    show_default=True,
    type=click.Path(dir_okay=False),
    callback=_plan_file_name,
    help="Where to write the plan: a .csv name writes CSV, any other name JSON, except a "
    "name of another format (.npz, .xlsx, ...), which is refused; '-' prints JSON.",
)
@click.pass_context
@friendly_errors
def plan_cmd(
    context: click.Context,
    preset_name: str,
    scenario_path: str | None,
    sequence_text: str | None,
    search_path: str | None,
    member: int | None,
    flights: int,
    seed: int,
    out: str,
) -> None:
    """Write the command plan of a sequence: per step and thruster the on-time (PWM, s),
    the commanded torque, each candidate's predicted rates (rad/s and deg/s), residual
    rate and attitude change, and the propellant figures."""
    from ..checks import csv_note_text
    from ..errors import InputError
    from ..search.plan import command_plan
    from .options import parse_sequence, refuse_decimal_levels

    if (sequence_text is None) == (search_path is None):
        raise InputError("give --sequence or --search (and --member), one of them")
    if member is not None and search_path is None:
        raise InputError("--member applies to --search")
    named = scenario_path is not None or (
        context.get_parameter_source("preset_name") is not click.core.ParameterSource.DEFAULT
    )
    scenario = load_scenario(preset_name, scenario_path)
    if search_path is not None:
        document = _search_document(search_path)
        sequence = _member_sequence(document, member)
        refuse_decimal_levels(sequence, search_path)
        scenario = _search_scenario(document, scenario, named_explicitly=named, path=search_path)
    else:
        assert sequence_text is not None
        sequence = parse_sequence(sequence_text, scenario)
    plan = command_plan(scenario, sequence, flights=flights, seed=seed)
    for warning in plan.warnings:
        click.echo(f"warning: {warning}", err=True)
    # Where the sequence came from, as the API's plan states it (scenario, job, member):
    # a plan handed on can be traced to its search and member, or to its sequence file.
    source: dict[str, object] = {}
    job: dict | None = None
    if search_path is not None:
        source = {
            "search": str(Path(search_path).resolve()),
            "member": "best" if member is None else member,
        }
        job = document.get("_job_facts")
        if (job or {}).get("status") == "cancelled":
            # As the service's plan of it says: its best is the best found before it stopped.
            source["job_status"] = "cancelled"
    elif sequence_text is not None and os.path.isfile(sequence_text):
        # A regular file only: a pipe's path (/dev/fd/63) names nothing once it is read.
        source = {"sequence_file": str(Path(sequence_text).resolve())}
    exported_at = datetime.now(UTC)
    # When it was written (UTC), as the service's plan JSON and every CSV say it.
    stamp = {"exported_at": _iso_utc(exported_at)}
    planned = (
        {"source": source, **stamp, **plan.to_dict()} if source else {**stamp, **plan.to_dict()}
    )
    if out == "-":
        click.echo(_strict_json(planned))
        return
    if out.lower().endswith(".csv"):
        # Paths are the user's text: JSON strings, so a comma or newline stays put.
        lines = "".join(
            f"# {key}: {csv_note_text(str(value)) if key in _PATHS else value}\n"
            for key, value in source.items()
        )
        if job is None:
            lines += f"# exported_at: {_iso_utc(exported_at)}\n"
        else:
            lines = _job_note_lines(job, exported_at) + lines
        write_output(out, lines + plan.to_csv())
    else:
        write_output(out, _strict_json(planned) + "\n")
    summary = plan.to_dict()
    click.echo(
        f"wrote {out}: {len(plan.sequence)} step{'' if len(plan.sequence) == 1 else 's'}, "
        f"impulse {plan.impulse_nms:.2f} N m s, "
        f"on-time {summary['propellant']['on_time_s']:.2f} s, largest residual rate "
        # Three significant digits, as the dashboard: a braking sequence's residual of
        # 1.3e-4 rad/s read "0.0001 rad/s (0.008 deg/s)" at :.4f, the two disagreeing.
        f"{significant(summary['residual_rate_max_rad_s'])} rad/s "
        f"({significant(summary['residual_rate_max_deg_s'])} deg/s)"
        + (
            # The prediction starts from rest: beside an initial-rate spread, say so and
            # what the spread adds to every flight.
            ", commanded (from rest: commanded_residual_rate_max); every flight also keeps "
            "the rate it started with, which no open-loop sequence removes: "
            f"{floor['mean_rad_s']:.4f} rad/s ({floor['mean_deg_s']:.3f} deg/s) on average, "
            f"{floor['p95_rad_s']:.4f} rad/s ({floor['p95_deg_s']:.3f} deg/s) on 95 % of "
            f"flights (initial_rate_sigma_rad_s = {floor['initial_rate_sigma_rad_s']:g})"
            if (floor := summary["initial_rate_floor"]) is not None
            else ""
        )
        + (
            f"; over {flights} flights a candidate: at least 95 % of flights end under "
            f"{summary['flights']['residual_rate_p95_bound_max_rad_s']:.4f} rad/s "
            f"({summary['flights']['residual_rate_p95_bound_max_deg_s']:.3f} deg/s) with 95 % "
            f"confidence; the 95th percentile of these flights "
            f"{summary['flights']['residual_rate_p95_max_rad_s']:.4f}, the fastest "
            f"{summary['flights']['residual_rate_max_rad_s']:.4f}; peak rate: at least 95 % "
            f"of flights under {summary['flights']['peak_rate_p95_bound_max_rad_s']:.4f} "
            f"rad/s ({summary['flights']['peak_rate_p95_bound_max_deg_s']:.3f} deg/s) with "
            "95 % confidence"
            if summary["flights"]
            else ""
        ),
        err=True,
    )


#: The source entries that are paths (the user's text).
_PATHS = ("search", "sequence_file")

#: Most bytes of a search's JSON ``--search`` reads (refused unread past it): an NSGA-II
#: search of the paper preset at L = 8 writes 93 KB (its front, baselines and curves),
#: so 100 MB, the telemetry limit, is a wrong file.
MAX_SEARCH_BYTES = 100_000_000


def _iso_utc(stamp: datetime) -> str:
    """A time as ISO 8601 in UTC with ``Z``, as the service's CSV lines write it."""
    return stamp.astimezone(UTC).isoformat().replace("+00:00", "Z")


def _job_note_lines(job: dict, exported_at: datetime) -> str:
    """The ``#`` lines every CSV of a service job begins with (which job it is and when
    it was written), for a plan of a job's search downloaded from the service.

    The same names in the same order as ``service.exports.job_notes`` (the core imports
    nothing from the service; a test holds the two to the same lines). The job's values
    come from a file: a stamp is written in UTC with ``Z``, and a text that is no plain
    word as a JSON string (a comma or newline in it cannot start a cell or a line).
    """
    from ..checks import csv_note_text

    def text(value: object) -> str:
        if value is None:
            return ""
        if isinstance(value, int) and not isinstance(value, bool):
            return str(value)
        plain = str(value)
        return plain if re.fullmatch(r"[\w.:+-]*", plain) else csv_note_text(plain)

    def stamp(value: object) -> str:
        try:
            parsed = datetime.fromisoformat(str(value))
        except ValueError:
            return text(value)
        return _iso_utc(parsed if parsed.tzinfo else parsed.replace(tzinfo=UTC))

    lines = [
        ("job_id", text(job.get("id"))),
        ("job_type", text(job.get("type"))),
        ("scenario_id", text(job.get("scenario_id"))),
        ("job_seed", text(job.get("seed"))),
        ("created_at", stamp(job.get("created_at")) if job.get("created_at") else ""),
        ("finished_at", stamp(job.get("finished_at")) if job.get("finished_at") else ""),
        ("exported_at", _iso_utc(exported_at)),
    ]
    return "".join(f"# {name}: {value}\n" for name, value in lines)


def _strict_json(document: dict) -> str:
    """Strict JSON: a non-finite figure as null (``json.dumps`` writes NaN, which strict
    parsers refuse)."""
    from ..checks import finite_or_none

    return json.dumps(finite_or_none(document), indent=2, allow_nan=False)


def _search_document(path: str) -> dict:
    from ..checks import DuplicateKeyError, loads_unique_keys, read_text
    from ..errors import InputError

    # Read outside the try: a file refused for its size or encoding says so, not "not a
    # search JSON".
    text = read_text(
        path,
        "a search's JSON",
        limit=MAX_SEARCH_BYTES,
        advice="is it a search (a job downloaded from the service, or inertia-id search --out)?",
        opening="{",
    )
    try:
        document = loads_unique_keys(text)
    except DuplicateKeyError as error:
        raise InputError(f"{path} has a {error}") from None
    except (ValueError, RecursionError) as error:
        raise InputError(f"{path} is not a search JSON: {error}") from None
    if not isinstance(document, dict):
        raise InputError(f"{path} is not a search JSON: it holds a {type(document).__name__}")
    if isinstance(document.get("result"), dict) and "type" in document:
        # A job as the service downloads it (GET /jobs/{id}/result): the search is its result.
        if document["type"] != "search":
            raise InputError(f"{path} is a {document['type']} job, not a search")
        job = document
        document = {**document["result"]}
        # Which job it is, for the lines a plan's CSV begins with (as the service's).
        facts = ("id", "type", "scenario_id", "seed", "created_at", "finished_at", "status")
        document["_job_facts"] = {key: job.get(key) for key in facts}
        # A job stored before results recorded their scenario: say whose it was.
        document.setdefault(
            "_job",
            f"it is job {job.get('id')} of scenario {job.get('scenario_id')}, whose "
            "document it does not hold (`GET /jobs/{id}/plan` plans on it)",
        )
    return document


def _search_scenario(
    document: dict, named: Scenario, *, named_explicitly: bool, path: str
) -> Scenario:
    """The scenario to plan a searched sequence on: the one the search recorded. A
    scenario named on the command line must be that one (its name aside,
    :meth:`~inertia_id.physics.scenario.Scenario.same_spacecraft`); a result that
    records none (written before results did) is planned on the named one, with a
    warning. A thruster of the recorded scenario that gives no torque is warned of on
    stderr, as :func:`~inertia_id.cli.options.load_scenario` warns of the named one's:
    once (a named scenario is the same spacecraft, already warned of)."""
    from pydantic import ValidationError

    from ..errors import InputError
    from ..physics.scenario import Scenario, idle_thruster_warning

    recorded = document.get("scenario")
    if recorded is None:
        why = document.get("_job", "it does not record the scenario it was searched on")
        click.echo(
            f"warning: {path}: {why}; planning on '{named.name}' (give --scenario or "
            "--preset to choose)",
            err=True,
        )
        return named
    if not isinstance(recorded, dict):
        raise InputError(f"{path}: its recorded scenario is not a scenario document")
    try:
        searched = Scenario.model_validate(recorded)
    except ValidationError as error:
        problems = "; ".join(
            f"{'.'.join(map(str, e['loc'])) or 'scenario'}: {e['msg']}" for e in error.errors()
        )
        raise InputError(f"{path}: its recorded scenario is not valid: {problems}") from None

    # Its name aside, and its levels to their last bits (a search's of then holds
    # numpy.linspace's: Scenario.same_spacecraft).
    if named_explicitly and not searched.same_spacecraft(named):
        raise InputError(
            f"{path} was searched on scenario '{searched.name}', which differs from the "
            f"scenario named ('{named.name}'); drop --scenario/--preset to plan on the "
            "searched one"
        )
    if not named_explicitly:
        idle = idle_thruster_warning(searched.torque_matrix)
        if idle is not None:
            click.echo(f"warning: {idle}", err=True)
    return searched


def _member_sequence(document: dict, member: int | None) -> list[list[int]]:
    from ..errors import InputError

    if member is None:
        best = document.get("best")
        sequence = best.get("sequence") if isinstance(best, dict) else None
        if not isinstance(sequence, list):
            raise InputError("the search JSON holds no best sequence (best.sequence, a list)")
        return sequence
    front = document.get("front")
    members = front.get("members") if isinstance(front, dict) else None
    if not isinstance(members, list):
        raise InputError("the search JSON holds no front (front.members, a list)")
    for entry in members:
        if isinstance(entry, dict) and entry.get("index") == member:
            sequence = entry.get("sequence")
            if not isinstance(sequence, list):
                raise InputError(f"front member {member} holds no sequence (a list)")
            return sequence
    raise InputError(f"the search's front has no member {member} (it holds {len(members)})")
