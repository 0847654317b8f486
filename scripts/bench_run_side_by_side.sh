#!/usr/bin/env bash
# `study run scenes/room.toml` (defaults but a 64² cube: the columns' work is the camera's, not the cube's) with this
# checkout and a second one side by side, alternating, on one render cache: round 0 fills the cache, rounds 1 and 2
# are warm. Prints each run's wall time and time split, and whether the two tables are equal value by value.
#   git worktree add /tmp/base 635ec81 && ln -s "$PWD/.venv" /tmp/base/.venv
#   bash scripts/bench_run_side_by_side.sh /tmp/base
# FIGURE=fig4 [BACKEND=llvm]: `study figure fig4 --backend llvm --images none` instead (the figure's 12 cases, its
# metrics.csv compared), on the render cache $CACHE when given (a warm one: the columns, traces and outputs are timed).
# CONFIG=configs/bench/fig4_samework.toml: that config instead; IMAGES=all (default none) and QUALITY=paper for both.
set -euo pipefail
base=${1:?usage: bench_run_side_by_side.sh OTHER_CHECKOUT}
here=$(cd "$(dirname "$0")/.." && pwd)
cache=${CACHE:-$(mktemp -d)}; outs=$(mktemp -d)
for round in 0 1 2; do
  for w in "$base" "$here"; do
    s=$(date +%s.%N)
    o="$outs/out-$(basename "$w")"
    if [ -n "${CONFIG:-}" ]; then   # a figure config file (configs/bench/fig4_samework.toml), IMAGES / QUALITY
      cmd=(figure --config "$CONFIG" --backend "${BACKEND:-llvm}" --images "${IMAGES:-none}" ${QUALITY:+--quality "$QUALITY"})
    elif [ -n "${FIGURE:-}" ]; then
      cmd=(figure "$FIGURE" --backend "${BACKEND:-llvm}" --images "${IMAGES:-none}" ${QUALITY:+--quality "$QUALITY"})
    else
      cmd=(run scenes/room.toml --set render.cube_res=64 --set render.cube_spp=16)
    fi
    (cd "$w" && PYTHONPATH=$w STUDY_PROGRESS_EVERY=0 "$w/.venv/bin/python" -m study "${cmd[@]}" --cache "$cache" \
      --out "$o" > "$outs/$(basename "$w")-$round.log" 2>&1)
    echo "round $round $(basename "$w"): $(echo "$(date +%s.%N) - $s" | bc) s; $(grep 'time split' "$outs/$(basename "$w")-$round.log")"
  done
done
t=table.csv; [ -n "${FIGURE:-}${CONFIG:-}" ] && t=metrics.csv
"$here/.venv/bin/python" - "$outs/out-$(basename "$base")/$t" "$outs/out-$(basename "$here")/$t" <<'PY'
import sys
import pandas as pd
a, b = (pd.read_csv(p) for p in sys.argv[1:])
cols = [c for c in a.columns if c not in ("seconds", "case_seconds")]
same = list(a.columns) == list(b.columns) and a[cols].equals(b[cols])
print(f"tables {a.shape}: {'equal value by value' if same else 'DIFFERENT'} (seconds aside)")
PY
