"""FLIP on the CPU: flip-evaluator (NVIDIA's C++, what the numpy backend uses) beside study's array FLIP on Dr.Jit's
LLVM backend (study/measure/flip.py), on the same image pairs in one run; medians of 3 warm calls each. Writes
``reports/performance/flip-cpu.md``.

    PYTHONPATH=. .venv/bin/python scripts/bench_flip.py
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    import flip_evaluator

    from study import runtime
    from study.codehash import code_hash
    from study.measure.metrics import flip_map

    runtime.require()
    rng = np.random.default_rng(0)
    lines = [
        "# FLIP on the CPU: flip-evaluator beside the array FLIP on LLVM",
        "",
        f"Median of 3 warm calls each, both in one run on this machine; code {code_hash(flip_map)}, flip-evaluator "
        f"{getattr(flip_evaluator, '__version__', '?')}. "
        "Made by `PYTHONPATH=. .venv/bin/python scripts/bench_flip.py`.",
        "",
        "| image | flip-evaluator s | LLVM s | LLVM / flip-evaluator | max abs difference |",
        "|---|---:|---:|---:|---:|",
    ]
    for n in (256, 1024):
        a = rng.random((n, n, 3)).astype(np.float32)
        b = (a + 0.05 * rng.standard_normal(a.shape)).clip(0).astype(np.float32)
        t, maps = {}, {}
        for be in ("numpy", "llvm"):
            maps[be] = flip_map(a, b, be)  # warm: the LLVM kernels traced and compiled
            ts = []
            for _ in range(3):
                t0 = time.perf_counter()
                flip_map(a, b, be)
                ts.append(time.perf_counter() - t0)
            t[be] = statistics.median(ts)
        diff = float(np.abs(maps["numpy"] - maps["llvm"]).max())
        lines.append(
            f"| {n}² | {t['numpy']:.3f} | {t['llvm']:.3f} | {t['llvm'] / t['numpy']:.2f}× | {diff:.1e} |"
        )
        print(lines[-1], flush=True)
    out = ROOT / "reports" / "performance" / "flip-cpu.md"
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
