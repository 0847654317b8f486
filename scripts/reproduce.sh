#!/usr/bin/env bash
# Set up (idempotent) and reproduce the paper's figures, the main sweep and the report into reports/.
# Finished work is cached (.cache/, reports/sweep-*/cases/): a second run only rebuilds what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
S=.venv/bin/study
$S figure fig4
$S figure fig5
$S figure fig6
$S caustics-sweep
$S sweep configs/sweep.toml --jobs 2
$S report
