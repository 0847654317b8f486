#!/usr/bin/env bash
# Idempotent set-up for a fresh Debian 12 / Python 3.11 machine (root, no GPU):
# a virtual environment in .venv with study and its dependencies, and a libLLVM that Dr.Jit's LLVM
# backend can use (Debian 12's default libLLVM 15 crashes it with "Cannot select ... fminimum").
#
#   bash scripts/setup.sh            the default and test extras (.venv about 1.4 GB)
#   bash scripts/setup.sh --video    also the video extra: ColorVideoVDP and PyTorch (.venv about 7 GB), for the
#                                    motion figure's JOD columns; without it they say "cvvdp not installed"
set -euo pipefail
cd "$(dirname "$0")/.."
extras=test
for arg in "$@"; do
  case "$arg" in
    --video) extras=test,video ;;
    *) echo "set-up: unknown option $arg; allowed: --video" >&2; exit 2 ;;
  esac
done
PY=${PYTHON:-python3}
export PIP_NO_CACHE_DIR=1  # a cache would keep the downloaded wheels (up to 3 GB) for good
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
stamp=.venv/.study-installed  # the extras installed, one line ("test" or "test,video")
had=$(cat "$stamp" 2>/dev/null || true)
case "$had" in *video*) extras=test,video ;; esac  # an earlier --video is kept, not taken away
if [ "$had" != "$extras" ] || [ pyproject.toml -nt "$stamp" ]; then
  # The default environment takes about 1.4 GB; the video extra adds PyTorch with its CUDA libraries (5.5 GB),
  # and pip holds the downloaded wheels until it has installed them. Refuse in one line where what is still
  # missing does not fit, rather than fail half-way with pip's OSError.
  case "$extras" in *video*) need_gb=7 ;; *) need_gb=2 ;; esac
  have_kb=$(du -sk .venv | cut -f1)
  free_kb=$(df -Pk .venv | awk 'NR==2 {print $4}')
  if [ $((need_gb * 1048576 - have_kb)) -gt "$free_kb" ]; then
    echo "set-up: $(pwd)/.venv needs about $need_gb GB ($extras extras), $((have_kb / 1048576)) GB are there and" \
      "$((free_kb / 1048576)) GB free on its disk (df -h $(pwd))" >&2
    exit 1
  fi
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[$extras]"
  echo "$extras" > "$stamp"
fi
# A working libLLVM for Dr.Jit: Debian's libllvm19 when apt can install it, otherwise the PyPI wheel
# karellen-llvm-core (study.backend finds either by itself).
if ! ls /usr/lib/x86_64-linux-gnu/libLLVM.so.19* >/dev/null 2>&1 && ! ls /usr/lib/*/libLLVM-19*.so* >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libllvm19 >/dev/null) \
      || .venv/bin/python -m pip install -q karellen-llvm-core
  else
    .venv/bin/python -m pip install -q karellen-llvm-core
  fi
fi
# A browser for the report's test (tests/report/test_html_browser.py drives it through Playwright): Debian's chromium, as
# root; without it that test is skipped and says why.
if ! command -v chromium >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
    || echo "set-up: could not install chromium; the browser test will be skipped"
fi
.venv/bin/python -c 'import study.runtime as r; print("study set-up ok; libLLVM:", r.require())'
