#!/usr/bin/env bash
# `study figure fig4` cold on this machine, two commits side by side in one run: each commit's tree exported to a
# temporary folder and run with a fresh study cache (Dr.Jit's kernel cache as it is: warm after the first run),
# in the order A B B A so that a drifting load weighs on both alike. Wall, user and system seconds per run go to
# $OUT/times.txt with the load average at the end of each run.
#
#   bash scripts/fig4_side_by_side.sh [BASE (default: HEAD~1)] [NEW (default: HEAD)]     OUT=/tmp/fig4-sbs
set -euo pipefail
cd "$(dirname "$0")/.."
BASE=${1:-HEAD~1}; NEW=${2:-HEAD}
OUT=${OUT:-/tmp/fig4-sbs}; rm -rf "$OUT"; mkdir -p "$OUT"
PY=${PY:-$PWD/.venv/bin/python}
for c in "$BASE" "$NEW"; do
  d="$OUT/tree-$(git rev-parse --short "$c")"; mkdir -p "$d"; git archive "$c" | tar -x -C "$d"
done
run() {  # label commit
  local d="$OUT/tree-$(git rev-parse --short "$2")"
  (cd "$d" && PYTHONPATH="$d" /usr/bin/time -f "%e wall %U user %S sys" -o "$OUT/time-$1.txt" \
    "$PY" -m study.cli figure fig4 --cache "$OUT/cache-$1" --out "$OUT/fig4-$1") > "$OUT/log-$1.txt" 2>&1
  echo "$1 $(git rev-parse --short "$2") $(cat "$OUT/time-$1.txt") load $(cut -d' ' -f1-3 /proc/loadavg)" \
    | tee -a "$OUT/times.txt"
}
run base1 "$BASE"; run new1 "$NEW"; run new2 "$NEW"; run base2 "$BASE"
