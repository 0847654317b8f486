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
# $REPRODUCE_JOBS commands at a time and $REPRODUCE_BACKEND (cuda where a GPU is, else llvm; numpy: the reference path; cuda: methods, renders and exact
# hits on the GPU) for every command but those $REPRODUCE_CPU (an extended regex) names, and the main sweep's
# $REPRODUCE_SWEEP_JOBS (2) cases at a time
# --verify (anywhere among the arguments): the committed tables are kept aside first (git's HEAD, or the tables as
# they are before this run where there is no .git), and at the end `study verify` compares the fresh tables with
# them row by row (within their intervals) → reports/verify/<backend>-vs-committed.md; exit 1 where any disagrees
args=(); VERIFY=
for a in "$@"; do if [ "$a" = --verify ]; then VERIFY=1; else args+=("$a"); fi; done
set -- ${args[@]+"${args[@]}"}
if [ "${1:-}" = "--no-setup" ]; then shift; else bash scripts/setup.sh "$@"; fi
if [ -n "$VERIFY" ]; then
  COMMITTED=$(mktemp -d)/reports
  if git rev-parse -q HEAD > /dev/null 2>&1; then
    mkdir -p "$COMMITTED" && git archive HEAD reports | tar -x -C "$(dirname "$COMMITTED")"
  else
    cp -r reports "$COMMITTED"
  fi
fi
S=${STUDY:-.venv/bin/study}
J=${REPRODUCE_JOBS:-2}
# longest first (their wall seconds in the cold llvm run on 2 cores, 6c6bdad, in brackets), so that the two slots
# end together; the calibration is one of them (not a study command: scripts/calibration.py)
commands=(
  "sweep configs/sweep.toml --jobs ${REPRODUCE_SWEEP_JOBS:-2}"   # the main sweep: position × cube resolution × occlusion [858]
  "figure fig5"                                 # [396]
  "figure fig4"                                 # [365]
  "convergence"                                 # localized's iterations 0…30, the marches' steps → reports/convergence/ [342]
  "figure fig_cornell"                          # [341]
  "figure fig_atrium"                           # [329]
  "figure fig_glossy"                           # rough objects against the lobe's truth, and the error split [254]
  "figure fig_lroom"                            # scenes nobody here wrote: two mesh rooms, Mitsuba's Cornell box [192]
  "caustics-sweep"                              # Figure 8 [181]
  "calibration"                                 # the intervals' coverage → reports/calibration.md [35–115]
  "figure fig_probes"                           # screen-space and multi-probe tracing beside the paper's [128]
  "figure fig_hitcache"                         # hit lighting: the exact hit shaded from a radiance cache, over res [127]
  "figure fig6"                                 # (after fig4: the room's probes cached) [127]
  "animate"                                     # sphere and torus in motion, 3 seeds → reports/animation/ [88]
  "sweep configs/sweep_atrium.toml"             # [81]
  "sweep configs/sweep_cornell.toml"            # [78]
  "figure fig_attic"                            # unequal roof slopes, an off-centre reference point [65]
  "sweep configs/sweep_lroom.toml"              # [56]
  "sweep configs/sweep_glossy.toml"             # [55]
)
t0=$(date +%s)
P=${STUDY_PYTHON:-.venv/bin/python}
# a GPU when one is there: --backend cuda where Dr.Jit's CUDA backend runs ($REPRODUCE_BACKEND set, even empty, decides),
# and Dr.Jit's LLVM backend on the CPU's cores where there is none (the methods' marches run 10–100× faster there
# than on numpy: multi_probe on a fig5 case 29.3 s on numpy, 2.7 s on LLVM with its kernels compiled, 0.3 s cached)
if [ -z "${REPRODUCE_BACKEND+set}" ]; then
  for b in cuda llvm; do
    if PYTHONPATH=.${PYTHONPATH:+:$PYTHONPATH} $P -c "from study.harness import budget; budget.check_backend('$b')" >/dev/null 2>&1; then
      REPRODUCE_BACKEND=$b; break
    fi
  done
  case ${REPRODUCE_BACKEND:-} in
    cuda) echo "reproduce: a GPU is here: every command with --backend cuda (REPRODUCE_BACKEND= keeps numpy)" ;;
    llvm) echo "reproduce: no GPU: every command with --backend llvm, Dr.Jit on the CPU's cores (REPRODUCE_BACKEND= keeps numpy)" ;;
  esac
fi
# $REPRODUCE_SKIP: an extended regex of commands left out (a lent host without the video extra skips "animate")
B=${REPRODUCE_BACKEND:+ --backend $REPRODUCE_BACKEND}
# the time it will take, before it starts: one line per command and the total on $J cores (study/harness/estimate.py:
# figures and sweeps as cases × the stage costs measured here, caustics, animation and convergence from their last run)
[ -n "${REPRODUCE_SKIP_CALIBRATION:-}" ] && REPRODUCE_SKIP="calibration${REPRODUCE_SKIP:+|$REPRODUCE_SKIP}"
mapfile -t todo < <(printf '%s\n' "${commands[@]}" | sed 's/ *#.*//' | grep -Ev "^(${REPRODUCE_SKIP:-\$^})\$")
PYTHONPATH=.${PYTHONPATH:+:$PYTHONPATH} $P -m study.harness.estimate --backend "${REPRODUCE_BACKEND:-numpy}" --jobs "$J" "${todo[@]}" | sed 's/^/reproduce: /' || true
printf '%s\n' "${todo[@]}" | sed -E "\\%^(calibration|${REPRODUCE_CPU:-\$^})\$%! s/\$/$B/" \
  | PYTHONPATH=.${PYTHONPATH:+:$PYTHONPATH} xargs -P "$J" -I CMD bash -c 'set -o pipefail
      case "CMD" in calibration) '"$P"' scripts/calibration.py ;; *) '"$S"' CMD ;; esac 2>&1 | sed -u "s|^|[CMD] |"'
$S pareto   # error vs measured ms per 1080p frame (the committed benches), fronts, budgets → reports/pareto/
$S report
PYTHONPATH=.${PYTHONPATH:+:$PYTHONPATH} $P scripts/headline.py --readme README.md   # README's "How sure" from the tables
if [ -n "$VERIFY" ]; then   # the fresh tables against the committed ones: one table a screen high
  $S verify reports --against "$COMMITTED" --out "reports/verify/${REPRODUCE_BACKEND:-numpy}-vs-committed.md" \
    || { echo "reproduce: some values disagree with the committed tables (reports/verify/)"; exit 1; }
fi
echo "reproduce: every report written in $(( $(date +%s) - t0 )) s"
