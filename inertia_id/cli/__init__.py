"""The ``inertia-id`` command line.

Every command takes a scenario (``--preset paper`` or ``--scenario FILE.json``) and a
seed; bad input ends with a one-line error naming the value, never a traceback. A command
parses its options, calls a pipeline of the core (:mod:`inertia_id.pipelines`) and prints.

One module per command group: :mod:`~inertia_id.cli.scenario` (scenario, simulate),
:mod:`~inertia_id.cli.classify` (train, sweep, identify), :mod:`~inertia_id.cli.search`,
:mod:`~inertia_id.cli.paper`, :mod:`~inertia_id.cli.plan`, :mod:`~inertia_id.cli.serve`
and :mod:`~inertia_id.cli.migrate` (the last two hand over to the service's own modules,
through :mod:`~inertia_id.cli.handover`);
:mod:`~inertia_id.cli.options` holds what they share. The group imports a command's
module only when the command is asked for (or its help listed), and the modules import
the core inside the commands, so
``inertia-id --help`` answers at once.
"""

from __future__ import annotations

import importlib
from typing import cast

import click

from .options import parse_sequence

__all__ = ["main", "parse_sequence"]

#: Command name -> "module:attribute" of its click command.
COMMANDS = {
    "identify": "inertia_id.cli.classify:identify_cmd",
    "migrate": "inertia_id.cli.migrate:migrate_cmd",
    "paper": "inertia_id.cli.paper:paper_cmd",
    "plan": "inertia_id.cli.plan:plan_cmd",
    "scenario": "inertia_id.cli.scenario:scenario_cmd",
    "search": "inertia_id.cli.search:search_cmd",
    "serve": "inertia_id.cli.serve:serve_cmd",
    "simulate": "inertia_id.cli.scenario:simulate_cmd",
    "sweep": "inertia_id.cli.classify:sweep_cmd",
    "train": "inertia_id.cli.classify:train_cmd",
}


class _LazyGroup(click.Group):
    """A group that imports a command's module when the command is first needed."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*super().list_commands(ctx), *COMMANDS})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in COMMANDS:
            module, _, attribute = COMMANDS[cmd_name].partition(":")
            return cast(click.Command, getattr(importlib.import_module(module), attribute))
        return super().get_command(ctx, cmd_name)


@click.group(cls=_LazyGroup)
@click.version_option(package_name="inertia-id")
def main() -> None:
    """Tell which known inertia configuration a spacecraft is in, from its rate
    response to a deliberately chosen thruster sequence."""
