"""``inertia-id plan``: a sequence as the commands a flight team uploads."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .options import friendly_errors, load_scenario, scenario_options

__all__ = ["plan_cmd"]


@click.command("plan")
@scenario_options
@click.option(
    "--sequence",
    "sequence_text",
    default=None,
    help="Level indices, rows separated by ';' (e.g. '4,4,4,0,0,0;0,0,0,4,4,4'), a JSON "
    "list of rows, or a JSON file holding one.",
)
@click.option(
    "--search",
    "search_path",
    type=click.Path(dir_okay=False, exists=True),
    default=None,
    help="A search JSON (from `search`): plan its front member --member (default its best).",
)
@click.option(
    "--member",
    type=click.IntRange(0),
    default=None,
    help="With --search: the front member's index (0 = the most accurate).",
)
@click.option(
    "--out",
    default="plan.json",
    show_default=True,
    type=click.Path(dir_okay=False),
    help="Where to write the plan: a .csv name writes CSV, anything else JSON; '-' prints JSON.",
)
@friendly_errors
def plan_cmd(
    preset_name: str,
    scenario_path: str | None,
    sequence_text: str | None,
    search_path: str | None,
    member: int | None,
    out: str,
) -> None:
    """Write the command plan of a sequence: per step and thruster the on-time (PWM, s),
    the commanded torque, each candidate's predicted rates (rad/s and deg/s), residual
    rate and attitude change, and the propellant figures."""
    from ..errors import InputError
    from ..search.plan import command_plan
    from .options import parse_sequence

    if (sequence_text is None) == (search_path is None):
        raise InputError("give --sequence or --search (and --member), one of them")
    if member is not None and search_path is None:
        raise InputError("--member applies to --search")
    if search_path is not None:
        document = json.loads(Path(search_path).read_text(encoding="utf-8"))
        sequence = _member_sequence(document, member)
    else:
        assert sequence_text is not None
        sequence = parse_sequence(sequence_text)
    scenario = load_scenario(preset_name, scenario_path)
    plan = command_plan(scenario, sequence)
    if out == "-":
        click.echo(json.dumps(plan.to_dict(), indent=2))
        return
    if out.lower().endswith(".csv"):
        Path(out).write_text(plan.to_csv(), encoding="utf-8")
    else:
        Path(out).write_text(json.dumps(plan.to_dict(), indent=2) + "\n", encoding="utf-8")
    summary = plan.to_dict()
    click.echo(
        f"wrote {out}: {len(plan.sequence)} steps, impulse {plan.impulse_nms:.2f} N m s, "
        f"on-time {summary['propellant']['on_time_s']:.2f} s, largest residual rate "
        f"{summary['residual_rate_max_rad_s']:.4f} rad/s "
        f"({summary['residual_rate_max_deg_s']:.3f} deg/s)",
        err=True,
    )


def _member_sequence(document: dict, member: int | None) -> list[list[int]]:
    from ..errors import InputError

    if member is None:
        best = document.get("best", {}).get("sequence")
        if best is None:
            raise InputError("the search JSON holds no best sequence")
        return list(best)
    members = (document.get("front") or {}).get("members", [])
    for entry in members:
        if entry.get("index") == member:
            return list(entry["sequence"])
    raise InputError(f"the search's front has no member {member} (it holds {len(members)})")
