#!/usr/bin/env bash
# The README's main command: installs the project, then runs the paper's pipeline on
# its preset (train, sweep, HTML report) into results/paper/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
. .venv/bin/activate
inertia-id paper "$@"
