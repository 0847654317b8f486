#!/usr/bin/env bash
# Set up (idempotent) and reproduce the paper's figures and the report into reports/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/study figure fig4
