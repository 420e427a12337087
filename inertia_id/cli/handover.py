"""A command that hands over to a module of the service (``python -m MODULE ARGS``).

The core imports nothing from the service, so ``inertia-id serve`` and ``inertia-id
migrate`` replace this process with the service's own module, which parses (and
documents: ``--help`` goes to it too) the options.
"""

from __future__ import annotations

import os
import sys

import click

__all__ = ["handover_command"]


def handover_command(name: str, module: str, help: str) -> click.Command:
    """The click command ``name``, listed with ``help``, that runs ``python -m module``
    with every argument it was given, unparsed."""

    @click.command(
        name,
        help=help,
        add_help_option=False,
        context_settings={"ignore_unknown_options": True, "allow_extra_args": True},
    )
    @click.argument("args", nargs=-1, type=click.UNPROCESSED)
    def command(args: tuple[str, ...]) -> None:
        os.execv(sys.executable, [sys.executable, "-m", module, *args])

    return command
