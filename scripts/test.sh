#!/usr/bin/env bash
# The README's test command: installs everything the tests need (the project, its test
# tools, docker-compose and Chromium), then lints,
# type-checks and runs the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
INERTIA_ID_EXTRAS=test,basilisk bash scripts/setup.sh
# System tools some tests drive, from Debian's packages where they are missing (as root):
# docker-compose validates docker-compose.yml offline; the dashboard's browser tests use
# Debian's Chromium through Playwright (Playwright's own browser download is never used).
apt_install() {
  local package=$1
  (apt-get install -y -q "$package" >/dev/null 2>&1 \
    || (apt-get update -q >/dev/null 2>&1 && apt-get install -y -q "$package" >/dev/null 2>&1)) \
    || echo "could not install $package; the tests that need it will skip (or fail in CI)"
}
command -v docker-compose >/dev/null || apt_install docker-compose
[ -x /usr/bin/chromium ] || apt_install chromium
. .venv/bin/activate
echo "== ruff"
ruff check inertia_id service app worker tests bench
ruff format --check inertia_id service app worker tests bench
echo "== mypy"
mypy
echo "== pytest"
# Three pytest-xdist workers, a test module each at a time (--dist loadscope: a module's
# fixtures are built once and its tests keep their order). One pytest process kept this
# 2-core machine about 30 % busy, waiting on the services, workers and browsers its tests
# start; more workers overlap those waits: two kept it about 51 % busy, three 58 %. The
# gain is within the spread of fresh-clone runs (README: "How long CI takes").
# At most 4 (tests/worker/conftest.py gives each a Redis database of its own).
# INERTIA_ID_TEST_WORKERS=0 runs the suite in one process.
workers=${INERTIA_ID_TEST_WORKERS:-3}
if [ "$workers" = "0" ]; then
  pytest "$@"
else
  pytest -n "$workers" --dist loadscope "$@"
fi
