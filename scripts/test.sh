#!/usr/bin/env bash
# The README's test command: installs everything the tests need, then lints,
# type-checks and runs the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
. .venv/bin/activate
echo "== ruff"
ruff check inertia_id app worker tests bench
ruff format --check inertia_id app worker tests bench
echo "== mypy"
mypy
echo "== pytest"
pytest "$@"
