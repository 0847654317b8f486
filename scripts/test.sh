#!/usr/bin/env bash
# Set up (idempotent) and run the default test suite: everything not marked slow, on both cores.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/python -m pytest -q -n 2 "$@"
