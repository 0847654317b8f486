"""A case's image columns on the CPU: numpy (scikit-image, the reference path) beside the array code on Dr.Jit's
LLVM backend (study/measure/pixels.py), on the same images in one run. One unit is what a case computes per trace
besides FLIP: RMSE, PSNR and SSIM against the oracle, the truth and Mitsuba (metrics.image_errors, FLIP off) and
the truth's columns (truth.columns). Frames of 1024² (paper) and 256², the object a disc as wide as fig4's sphere
(a fifth of the frame's width across); the two paths alternate, median of the warm calls. Writes
``reports/performance/image-columns-cpu.md``, with the LLVM-FLIP / flip-evaluator ratio of
``reports/performance/flip-cpu.md`` (scripts/bench_flip.py) beside it.

    PYTHONPATH=. .venv/bin/python scripts/bench_image_columns.py [--repeats 7] [--sizes 1024 256]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
OUT = ROOT / "reports" / "performance" / "image-columns-cpu.md"


def columns(images: dict, mask: np.ndarray, backend: str) -> dict:
    """One trace's image columns other than FLIP, as a case computes them on ``backend``."""
    from study.measure import metrics, truth

    img, t = images["image"], images["truth"]
    out = {}
    for suffix in ("oracle", "truth", "mitsuba"):
        ref = t.image if suffix == "truth" else images[suffix]
        out |= metrics.image_errors(ref, img, mask=mask, suffix=suffix, backend=backend, with_flip=False)
    return out | truth.columns(img, t, images["mitsuba"], mask=mask, backend=backend)


def frame(n: int, rng) -> tuple[dict, np.ndarray]:
    from study.measure.truth import Truth

    yy, xx = np.mgrid[:n, :n]
    mask = (yy - 0.48 * n) ** 2 + (xx - 0.55 * n) ** 2 < (0.1 * n) ** 2

    def img(scale=1.0):
        return rng.random((n, n, 3)) * 1.5 * scale

    base = img()
    t = Truth(base, rng.normal(0, 0.02, base.shape), np.zeros((1, 3)), rng.normal(0, 0.02, base.shape))
    return {
        "image": base + rng.normal(0, 0.1, base.shape),
        "truth": t,
        "oracle": img(),
        "mitsuba": img(),
    }, mask


def flip_ratio() -> list[str]:
    """The LLVM-FLIP rows of reports/performance/flip-cpu.md, as they stand."""
    f = ROOT / "reports" / "performance" / "flip-cpu.md"
    rows = (
        [ln for ln in f.read_text().splitlines() if ln.startswith("| ") and "²" in ln] if f.is_file() else []
    )
    head = (
        "| image | flip-evaluator s | LLVM s | LLVM / flip-evaluator | max abs difference |\n"
        + "|---:" * 5
        + "|"
    )
    return (
        [head, *rows] if rows else ["(reports/performance/flip-cpu.md not found: run scripts/bench_flip.py)"]
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1024, 256], help="frame sizes (n for n²)")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    from study import runtime
    from study.codehash import code_hash
    from study.measure import metrics, pixels

    runtime.require()
    threshold, metrics.LLVM_MIN_PIXELS = metrics.LLVM_MIN_PIXELS, 0  # the array code at every size, here
    rng = np.random.default_rng(0)
    rows, verdicts = [], []
    for n in args.sizes:
        images, mask = frame(n, rng)
        ref = columns(images, mask, "numpy")
        got = columns(images, mask, "llvm")  # warm: kernels traced and compiled
        diff = max(abs(got[k] - ref[k]) for k in ref if np.isfinite(ref[k]))
        if not diff <= 1e-5:  # the two paths measure the same numbers, or the timing means nothing
            raise SystemExit(f"{n}²: LLVM and numpy differ by {diff:g}")
        times = {"numpy": [], "llvm": []}
        for _ in range(args.repeats):  # alternating, so a busy machine slows both alike
            for be in times:
                t0 = time.perf_counter()
                columns(images, mask, be)
                times[be].append(time.perf_counter() - t0)
        t = {be: statistics.median(v) for be, v in times.items()}
        crop = metrics._crop(mask, 8)[0].size
        rows.append(
            f"| {n}² | {int(mask.sum())} | {crop} | {t['numpy']:.4f} | {t['llvm']:.4f} | "
            f"{t['llvm'] / t['numpy']:.2f}× | {diff:.1e} |"
        )
        verdicts.append(t["llvm"] < t["numpy"])
        print(rows[-1], flush=True)
    faster = all(verdicts)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [
        "# A case's image columns on the CPU: numpy (scikit-image) beside the array code on LLVM",
        "",
        "One unit is one trace's image columns other than FLIP: RMSE, PSNR and SSIM against the oracle, the truth "
        "and Mitsuba (`metrics.image_errors`) and the truth's columns (`truth.columns`); the object a disc a fifth "
        f"of the frame wide. Median of {args.repeats} warm calls each, the two paths alternating in one run on "
        f"this machine ({os.cpu_count()} CPU cores, load average {load:.1f} at the end; numpy runs in one "
        f"thread, LLVM on every core); code {code_hash(pixels.errors_on, metrics.image_errors)}. Made by "
        "`PYTHONPATH=. .venv/bin/python scripts/bench_image_columns.py`.",
        "",
        "| frame | object pixels | SSIM crop pixels | numpy s | LLVM s | LLVM / numpy | max abs difference |",
        "|---|---:|---:|---:|---:|---:|---:|",
        *rows,
        "",
        f"A case with `--backend llvm` measures these columns on **{metrics.LLVM_IMAGES}** from crops of "
        f"{threshold} pixels on (`study.measure.metrics.LLVM_MIN_PIXELS`; SSIM's crop is the object's bounding box "
        "+ 8 px, in the table) and with scikit-image below, where LLVM's fixed "
        f"cost per kernel loses; in this run the array code was "
        f"{'faster at every size measured' if faster else 'not faster at every size'}. `--backend numpy` (the "
        "default, and every committed table) keeps scikit-image and numpy; `--backend cuda` measures them on the GPU.",
        "",
        "FLIP on the CPU, as `scripts/bench_flip.py` measured it (reports/performance/flip-cpu.md): a case on "
        "`--backend llvm` runs FLIP on LLVM, on `numpy` flip-evaluator.",
        "",
        *flip_ratio(),
    ]
    metrics.LLVM_MIN_PIXELS = threshold
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
