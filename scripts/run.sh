#!/usr/bin/env bash
# The README's main command: installs the project, then runs the service on the embedded
# default (dashboard and API on 127.0.0.1:8000 and one worker; SQLite and the filesystem broker under
# inertia-id-data/). Arguments go to `inertia-id serve` (e.g. --port, --workers).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
. .venv/bin/activate
inertia-id serve "$@"
