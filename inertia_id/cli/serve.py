"""``inertia-id serve``: the web service and its workers, handed over to ``app.serve``."""

from __future__ import annotations

import os
import sys

import click

__all__ = ["serve_cmd"]


@click.command(
    "serve",
    add_help_option=False,
    context_settings={"ignore_unknown_options": True, "allow_extra_args": True},
)
@click.argument("serve_args", nargs=-1, type=click.UNPROCESSED)
def serve_cmd(serve_args: tuple[str, ...]) -> None:
    """Run the web service and its workers on this machine (--host, --port, --data-dir,
    --workers; see `inertia-id serve --help`)."""
    # The core imports nothing from the service: hand over to `python -m app.serve`, which
    # parses (and documents) the options.
    os.execv(sys.executable, [sys.executable, "-m", "app.serve", *serve_args])
