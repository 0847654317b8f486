#!/usr/bin/env bash
# Idempotent set-up for a fresh Debian 12 / Python 3.11 machine (root, no GPU):
# a virtual environment in .venv with study and its dependencies, and a libLLVM that Dr.Jit's LLVM
# backend can use (Debian 12's default libLLVM 15 crashes it with "Cannot select ... fminimum").
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
export PIP_NO_CACHE_DIR=1  # a cache would keep the downloaded wheels (about 3 GB) for good
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
stamp=.venv/.study-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  # The environment takes about 7 GB (PyTorch with its CUDA libraries, for the video extra, is 5.5 GB of it), and
  # pip holds the downloaded wheels (about 3 GB) until it has installed them. Refuse in one line
  # where not even the environment fits, rather than fail half-way with pip's OSError.
  need_gb=7
  free_gb=$(df -Pk .venv | awk 'NR==2 {print int($4 / 1048576)}')
  if [ "$(du -sk .venv | cut -f1)" -lt 1048576 ] && [ "$free_gb" -lt "$need_gb" ]; then
    echo "set-up: $(pwd)/.venv needs about $need_gb GB free on its disk, $free_gb GB are (df -h $(pwd))" >&2
    exit 1
  fi
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e '.[test,video]'
  touch "$stamp"
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
# A browser for the report's test (tests/test_html_browser.py drives it through Playwright): Debian's chromium, as
# root; without it that test is skipped and says why.
if ! command -v chromium >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
    || echo "set-up: could not install chromium; the browser test will be skipped"
fi
.venv/bin/python -c 'import study.runtime as r; print("study set-up ok; libLLVM:", r.require())'
