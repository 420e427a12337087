"""``python -m inertia_id.cli``: the ``inertia-id`` command."""

from . import main

main()
