"""``inertia-id migrate``: the database's schema to this code's head, handed over to
``service.store.migrate``."""

from __future__ import annotations

from .handover import handover_command

__all__ = ["migrate_cmd"]

migrate_cmd = handover_command(
    "migrate",
    "service.store.migrate",
    "Apply the service database's migrations up to this code's newest (--check, "
    "--data-dir; see `inertia-id migrate --help`).",
)
