"""The image columns on a GPU (study/measure/pixels.py with backend cuda) against scikit-image/numpy: values within
1e-5 on synthetic images (the mask inside, at the frame's edge, 1024²) and one trace's columns side by side
(scripts/bench_image_columns.py's unit, 1024² and 256² frames, median of 7). Run on a GPU machine from the repository
root: ``bash scripts/device_run.sh pixels`` (or ``python3 scripts/pixels_cuda.py`` where Dr.Jit finds CUDA)."""

import statistics
import sys
import time

import numpy as np

sys.path.insert(0, ".")
import runpy

from study.measure import metrics, pixels

b = runpy.run_path("scripts/bench_image_columns.py")
BE = sys.argv[1] if len(sys.argv) > 1 else "cuda"  # llvm: the same check on the CPU
rng = np.random.default_rng(0)
worst = 0.0
for n, cy, cx, r in ((64, 30, 35, 14), (64, 2, 60, 12), (256, 128, 140, 40), (1024, 500, 560, 102)):
    yy, xx = np.mgrid[:n, :n]
    mask = (yy - cy) ** 2 + (xx - cx) ** 2 < r * r
    a = rng.random((n, n, 3)) * 1.4
    t = a + rng.normal(0, 0.05, a.shape)
    want = (metrics.rmse(a, t, mask=mask), metrics.psnr(a, t, mask=mask), metrics.ssim(a, t, mask=mask))
    got = pixels.errors_on(a, t, mask=mask, backend=BE)
    got2 = metrics.image_errors(a, t, mask=mask, suffix="x", backend=BE, with_flip=False)
    d = max(
        max(abs(g - w) for g, w in zip(got, want)),
        max(abs(got2[f"{m}_x"] - w) for m, w in zip(("rmse", "psnr", "ssim"), want)),
    )
    worst = max(worst, d)
    print(f"{n}² mask at ({cy},{cx}) r={r}: max |{BE} - numpy| = {d:.2e}", flush=True)
for n in (1024, 256):
    images, mask = b["frame"](n, rng)
    ref = b["columns"](images, mask, "numpy")
    got = b["columns"](images, mask, BE)
    diff = max(abs(got[k] - ref[k]) for k in ref if np.isfinite(ref[k]))
    worst = max(worst, diff)
    ts = {"numpy": [], BE: []}
    for _ in range(7):
        for be in ts:
            t0 = time.perf_counter()
            b["columns"](images, mask, be)
            ts[be].append(time.perf_counter() - t0)
    tn, tc = statistics.median(ts["numpy"]), statistics.median(ts[BE])
    print(
        f"columns {n}²: numpy {tn:.4f} s, {BE} {tc:.4f} s ({tc / tn:.2f}x), max diff {diff:.1e}", flush=True
    )
print("WORST", worst, "OK" if worst <= 1e-5 else "FAIL")
