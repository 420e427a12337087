"""``inertia-id serve``: the web service and its workers, handed over to ``app.serve``."""

from __future__ import annotations

from .handover import handover_command

__all__ = ["serve_cmd"]

serve_cmd = handover_command(
    "serve",
    "app.serve",
    "Run the web service and its workers on this machine (--host, --port, --data-dir, "
    "--workers; see `inertia-id serve --help`).",
)
