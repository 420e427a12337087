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
# pip's own exit status decides; its "location is ignored" notes about this machine's
# extra package indexes are filtered from the log only.
quiet_pip() {
  local log status
  log=$(mktemp)
  if pip install --quiet --disable-pip-version-check "$@" >"$log" 2>&1; then status=0; else status=$?; fi
  grep -v "is ignored: it is neither a file nor a directory" "$log" || true
  rm -f "$log"
  return "$status"
}
quiet_pip --upgrade pip
quiet_pip "torch==2.13.0"
# Extras: run.sh needs none beyond the tests' tools; test.sh adds basilisk (the
# independent simulator the tests check against).
quiet_pip -e ".[${INERTIA_ID_EXTRAS:-test}]"
python -c "import inertia_id, tslearn, torch; print('installed inertia-id', inertia_id.__version__, '| torch', torch.__version__)"
