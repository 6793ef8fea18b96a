#!/usr/bin/env bash
# Set-up and tests: installs everything, then runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --web
export VOXGI_REQUIRE_WEB=1  # the bake-file checks by other tools run, never skip
exec .venv/bin/python -m pytest -q -ra "$@"
