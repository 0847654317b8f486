#!/usr/bin/env bash
# Run the default test tier N times (default 10) in one fresh clone of HEAD and list every test that failed at
# least once, with each run's wall time: `bash scripts/flaky.sh 10`. The clone gets its own .venv (scripts/setup.sh,
# once); before each run everything git does not track except .venv is removed (caches, outputs), so each run
# starts as CI's does. Logs and the summary go to $FLAKY_DIR (default /tmp/study-flaky).
set -uo pipefail
n=${1:-10}
src=$(cd "$(dirname "$0")/.." && pwd)
dir=${FLAKY_DIR:-/tmp/study-flaky}
rm -rf "$dir" && mkdir -p "$dir"
git clone -q "$src" "$dir/clone"
cd "$dir/clone"
bash scripts/setup.sh > "$dir/setup.log" 2>&1 || { echo "set-up failed: $dir/setup.log"; exit 3; }
: > "$dir/failed.txt"
for i in $(seq 1 "$n"); do
  git clean -qxdf -e .venv
  t0=$(date +%s)
  .venv/bin/python -m pytest -q -n 2 -p no:cacheprovider -rfE > "$dir/run-$i.log" 2>&1
  rc=$?
  t=$(( $(date +%s) - t0 ))
  grep -E '^(FAILED|ERROR) ' "$dir/run-$i.log" | sed 's/^\(FAILED\|ERROR\) \([^ ]*\).*/\2/' \
    | tee -a "$dir/failed.txt" > /dev/null                                  # errors in set-up count too
  echo "run $i: exit $rc in ${t} s — $(tail -n 1 "$dir/run-$i.log")" | tee -a "$dir/runs.txt"
done
echo "tests that failed at least once (count):"
sort "$dir/failed.txt" | uniq -c | sort -rn
[ ! -s "$dir/failed.txt" ]
