#!/usr/bin/env bash
# Creates .venv (if missing) and installs the project with its test tools, printing each
# step with the seconds since the start and pip's own lines as it downloads and installs
# (a first install downloads about 1 GB, torch's CPU wheel the largest part).
# torch is pinned first: the CPU wheel for that exact version is what the search
# (stable-baselines3) needs, and an unpinned torch would pull gigabytes of CUDA packages.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
START=$SECONDS
step() { echo "[setup $((SECONDS - START)) s] $*"; }
if [ ! -x .venv/bin/python ]; then
  step "creating .venv with $("$PYTHON" --version 2>&1)"
  "$PYTHON" -m venv .venv
fi
. .venv/bin/activate
# pip's exit status decides; its lines stream as they come, less those that say nothing
# (already-installed requirements, notes about this machine's extra package indexes).
pip_install() {
  local statuses
  set +e
  pip install --disable-pip-version-check --progress-bar off "$@" 2>&1 \
    | grep --line-buffered -v -e "is ignored: it is neither a file nor a directory" \
      -e "^Requirement already satisfied"
  statuses=("${PIPESTATUS[@]}")
  set -e
  return "${statuses[0]}"
}
step "upgrading pip"
pip_install --quiet --upgrade pip
step "installing torch 2.13.0 (CPU wheel)"
pip_install "torch==2.13.0"
# Extras: run.sh needs none beyond the tests' tools; test.sh adds basilisk (the
# independent simulator the tests check against).
step "installing inertia-id and its dependencies (extras: ${INERTIA_ID_EXTRAS:-test})"
pip_install -e ".[${INERTIA_ID_EXTRAS:-test}]"
python -c "import inertia_id, tslearn, torch; print('installed inertia-id', inertia_id.__version__, '| torch', torch.__version__)"
step "done"
