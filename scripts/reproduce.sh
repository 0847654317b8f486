#!/usr/bin/env bash
# Set up (idempotent) and reproduce the paper's figures, the sweeps and the report into reports/.
# Finished work is cached (.cache/, reports/sweep-*/cases/): a second run only rebuilds what changed.
# The commands are independent (each writes its own folder under reports/; the cache is shared safely), so two run
# at a time, longest first, to keep both cores busy; each output line is prefixed by its command. The report last.
# `bash scripts/reproduce.sh --video` sets up with the video extra first (cvvdp, PyTorch: the motion figure's JOD
# columns; the committed report was made so), without it those columns say "cvvdp not installed".
set -euo pipefail
cd "$(dirname "$0")/.."
# --no-setup: use what is installed (a lent GPU host, scripts/device_run.sh reproduce), with $STUDY as the command,
# $REPRODUCE_JOBS commands at a time and $REPRODUCE_BACKEND (numpy by default; cuda: methods, renders and exact
# hits on the GPU) for every command but those $REPRODUCE_CPU (an extended regex) names, and the main sweep's
# $REPRODUCE_SWEEP_JOBS (2) cases at a time
if [ "${1:-}" = "--no-setup" ]; then shift; else bash scripts/setup.sh "$@"; fi
S=${STUDY:-.venv/bin/study}
J=${REPRODUCE_JOBS:-2}
commands=(
  "sweep configs/sweep.toml --jobs ${REPRODUCE_SWEEP_JOBS:-2}"   # the main sweep: position × cube resolution × occlusion
  "figure fig5"
  "figure fig4"
  "caustics-sweep"                              # Figure 8
  "figure fig_lroom"                            # scenes nobody here wrote: two mesh rooms, Mitsuba's Cornell box
  "figure fig_atrium"
  "figure fig_cornell"
  "figure fig6"
  "sweep configs/sweep_cornell.toml"
  "sweep configs/sweep_atrium.toml"
  "sweep configs/sweep_lroom.toml"
  "animate"                                     # sphere and torus in motion, 3 seeds (~20 min) → reports/animation/
  "figure fig_glossy"                           # rough objects against the lobe's truth, and the error split
  "sweep configs/sweep_glossy.toml"
  "figure fig_attic"                            # unequal roof slopes, an off-centre reference point
  "figure fig_hitcache"                         # hit lighting: the exact hit shaded from a radiance cache, over res
  "figure fig_probes"                           # screen-space and multi-probe tracing beside the paper's
  "convergence"                                 # localized's iterations 0…30, the marches' steps → reports/convergence/
)
t0=$(date +%s)
# $REPRODUCE_SKIP: an extended regex of commands left out (a lent host without the video extra skips "animate")
B=${REPRODUCE_BACKEND:+ --backend $REPRODUCE_BACKEND}
printf '%s\n' "${commands[@]}" | sed 's/ *#.*//' | grep -Ev "^(${REPRODUCE_SKIP:-\$^})\$" | sed -E "\\%^(${REPRODUCE_CPU:-\$^})\$%! s/\$/$B/" \
  | xargs -P "$J" -I CMD bash -c 'set -o pipefail; '"$S"' CMD 2>&1 | sed -u "s|^|[CMD] |"'
[ -n "${REPRODUCE_SKIP_CALIBRATION:-}" ] \
  || PYTHONPATH=. ${STUDY_PYTHON:-.venv/bin/python} scripts/calibration.py   # the intervals' coverage → reports/calibration.md
$S pareto   # error vs measured ms per 1080p frame (the committed benches), fronts, budgets → reports/pareto/
$S report
PYTHONPATH=. ${STUDY_PYTHON:-.venv/bin/python} scripts/headline.py --readme README.md   # README's "How sure" from the tables
echo "reproduce: every report written in $(( $(date +%s) - t0 )) s"
