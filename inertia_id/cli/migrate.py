"""``inertia-id migrate``: the database's schema to this code's head, handed over to
``service.store.migrate``."""

from __future__ import annotations

import os
import sys

import click

__all__ = ["migrate_cmd"]


@click.command(
    "migrate",
    add_help_option=False,
    context_settings={"ignore_unknown_options": True, "allow_extra_args": True},
)
@click.argument("migrate_args", nargs=-1, type=click.UNPROCESSED)
def migrate_cmd(migrate_args: tuple[str, ...]) -> None:
    """Apply the service database's migrations up to this code's newest (--check,
    --data-dir; see `inertia-id migrate --help`)."""
    # The core imports nothing from the service: hand over to `python -m
    # service.store.migrate`, which parses (and documents) the options.
    os.execv(sys.executable, [sys.executable, "-m", "service.store.migrate", *migrate_args])
