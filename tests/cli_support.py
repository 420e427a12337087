"""Running ``inertia-id`` in-process, as the command-line and worker-parity tests do.

Tests import this module as ``cli_support`` (``tests/`` is on ``sys.path``, see
``service_support``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from click.testing import CliRunner, Result

from inertia_id.cli import main


def run_cli(args: Sequence[str]) -> Result:
    """``inertia-id ARGS``, which must succeed (its output is the failure message)."""
    result = CliRunner().invoke(main, list(args))
    assert result.exit_code == 0, result.output
    return result


def run_cli_json(args: Sequence[str], out: Path) -> tuple[Any, Result]:
    """``inertia-id ARGS --out OUT``, which must succeed: OUT's JSON document, and the run."""
    result = run_cli([*args, "--out", str(out)])
    return json.loads(out.read_text()), result
