#!/usr/bin/env bash
# Creates .venv (if missing) and installs the project with its test tools.
# torch is pinned first: the CPU wheel for that exact version is what the search
# (stable-baselines3) needs, and an unpinned torch would pull gigabytes of CUDA packages.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
. .venv/bin/activate
pip install --quiet --disable-pip-version-check --upgrade pip 2>&1 | grep -v "is ignored" || true
pip install --quiet --disable-pip-version-check "torch==2.13.0" 2>&1 | grep -v "is ignored" || true
pip install --quiet --disable-pip-version-check -e ".[test]" 2>&1 | grep -v "is ignored" || true
python -c "import inertia_id, tslearn, torch; print('installed inertia-id', inertia_id.__version__, '| torch', torch.__version__)"
