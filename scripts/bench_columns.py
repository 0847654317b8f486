"""The image columns' cost per method row, column group by column group: the per-method path a case took before
issue 52 (one image at a time, FLIP over the whole frame) beside the batched one (study/measure/batched.py: the
methods' images stacked, what depends on a reference once), on synthetic 1024² frames (the object a disc a fifth of
the frame wide, a third of its pixels unheld by the oracle), both paths in one run, their values compared. Writes
the table between the ``bench_columns`` markers of reports/performance.md.

    PYTHONPATH=. .venv/bin/python scripts/bench_columns.py [--backends numpy llvm] [--size 1024] [--methods 4]
    PYTHONPATH=. .venv/bin/python scripts/bench_columns.py --backends cuda --out reports/performance/columns-cuda.md
    PYTHONPATH=. .venv/bin/python scripts/bench_columns.py --spatial-before 63fdc9a --methods 15

(the second on a GPU machine: the same table for CUDA, written to its own file; --out '' prints only; the third
times only the spatial intervals a method row takes, a revision's per-method calls beside today's batched ones).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
REPORT = ROOT / "reports" / "performance.md"
BEGIN, END = "<!-- bench_columns -->", "<!-- /bench_columns -->"


def frame(n: int, methods: int, rng):
    """A case's references (``case._Refs``) and ``methods`` images of an n² frame."""
    from study.measure.truth import Truth

    yy, xx = np.mgrid[:n, :n]
    mask = (yy - 0.48 * n) ** 2 + (xx - 0.55 * n) ** 2 < (0.1 * n) ** 2
    held = ~(mask & (xx > 0.58 * n))  # a third of the object's pixels hold hits the views do not

    def img():
        return (rng.random((n, n, 3)) * 1.2).astype(np.float32)

    bg = img()
    truth = bg.copy()
    truth[mask] = rng.random((int(mask.sum()), 3)) * 1.2
    noise = np.where(mask[..., None], rng.normal(0, 0.02, (n, n, 3)), 0).astype(np.float32)
    mnoise = rng.normal(0, 0.02, (n, n, 3)).astype(np.float32)
    t = Truth(truth, noise, np.zeros((1, 3)), mnoise, ev=0.0)
    oracle = truth + np.where(mask[..., None], rng.normal(0, 0.05, (n, n, 3)), 0).astype(np.float32)
    images = np.stack([truth + np.where(mask[..., None], rng.normal(0, 0.1 * (i + 1), (n, n, 3)), 0)
                       for i in range(methods)]).astype(np.float32)  # fmt: skip
    r = SimpleNamespace(truth=t, mitsuba=truth + mnoise, oracle=oracle, oracle_seed=oracle + 0.01,
                        oracle_coarse=oracle - 0.01, held_px=held, on_held=mask & held, mask=mask,
                        sigma=float(np.sqrt(np.mean(noise[mask] ** 2))), against=("oracle", "truth"))  # fmt: skip
    return r, images


def groups(r, imgs, backend: str):
    """(name, per-method path, batched path) of each column group: functions of no argument."""
    from study.measure import batched, case_columns, metrics, split, truth

    keep = (r.held_px | ~r.mask)[..., None]
    refs = np.where(keep, r.oracle, imgs)
    sigma = truth.noise_rms(r.truth.noise, r.mask)
    maps = {}

    def old_truth():
        out = []
        for img in imgs:
            fmap = metrics._flip_frame(r.truth.image, img, backend)  # the whole frame, as before
            out.append(metrics.image_errors(r.truth.image, img, mask=r.mask, suffix="truth", flip_emap=fmap,
                                            backend=backend))  # fmt: skip
        return out

    def new_truth():
        fm = batched.flip_maps(r.truth.image, imgs, backend)
        maps["truth"] = fm
        return batched.errors(r.truth.image, imgs, mask=r.mask, suffix="truth", backend=backend, with_flip=True,
                              fvals=[f[r.mask] for f in fm])  # fmt: skip

    def old_truth_cols():
        return [truth.columns(img, r.truth, r.mitsuba, mask=r.mask, backend=backend) for img in imgs]

    def new_truth_cols():
        e = batched.errors(r.mitsuba, imgs, mask=r.mask, suffix="m", backend=backend, with_flip=False)
        rt = batched._rmse(r.truth.image[r.mask], imgs[:, r.mask])
        return batched.truth_columns(imgs, r.truth, r.mitsuba, mask=r.mask, rmse_truth=list(rt),
                                     rmse_mitsuba=[c["rmse_m"] for c in e])  # fmt: skip

    def split_args():
        return (r.truth.image, r.truth.noise, r.oracle, r.oracle_seed, r.oracle_coarse)

    return [
        ("RMSE, PSNR, SSIM, FLIP against the oracle (its own pixels, each image its reference)",
         lambda: [metrics.image_errors(refs[i], img, mask=r.on_held, suffix="oracle", backend=backend)
                  for i, img in enumerate(imgs)],
         lambda: batched.errors(r.oracle, imgs, mask=r.on_held, suffix="oracle", backend=backend, with_flip=True,
                                refs=refs)),
        ("RMSE, PSNR, SSIM, FLIP against the truth (with the FLIP map of the frame)", old_truth, new_truth),
        ("RMSE, PSNR, SSIM against Mitsuba",
         lambda: [metrics.image_errors(r.mitsuba, img, mask=r.mask, suffix="mitsuba", backend=backend,
                                       with_flip=False) for img in imgs],
         lambda: batched.errors(r.mitsuba, imgs, mask=r.mask, suffix="mitsuba", backend=backend, with_flip=False)),
        ("the truth's columns (relMSE, debiased, exposed relMSE and its interval, noise, fireflies)",
         old_truth_cols, new_truth_cols),
        ("pixel intervals (case_columns.pixel_columns: RMSE, relMSE, FLIP; per method in both)",
         lambda: [case_columns.pixel_columns(img, r.truth.image, mask=r.mask, sigma=sigma, rel_eps=truth.REL_EPS)
                  for img in imgs],
         lambda: [case_columns.pixel_columns(img, r.truth.image, mask=r.mask, sigma=sigma, rel_eps=truth.REL_EPS)
                  for img in imgs]),
        ("the error split with its intervals",
         lambda: [split.split_columns(img, *split_args(), mask=r.mask, held_px=r.held_px) for img in imgs],
         lambda: split.split_stack(imgs, *split_args(), mask=r.mask, held_px=r.held_px)),
    ]  # fmt: skip


def _module_at(rev: str, path: str):
    """The module at ``path`` as it stood at git revision ``rev`` (a self-contained module: the spatial intervals
    before study.stats.region)."""
    import importlib.util
    import subprocess
    import tempfile

    text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:{path}"], capture_output=True, text=True,
                          check=True).stdout  # fmt: skip
    f = Path(tempfile.mkdtemp()) / "spatial_before.py"
    f.write_text(text)
    spec = importlib.util.spec_from_file_location("spatial_before", f)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def spatial_groups(r, imgs, old):
    """(name, before, now) of each group of spatial intervals a case's method rows take: ``old`` the spatial
    module before (one call per method, the mask's work in each), now study.stats.spatial (every method in one
    call, the mask's work once per case). Rays: 4 per object pixel, flags from a correlated field per method."""
    from scipy import ndimage

    from study.measure import split
    from study.stats import spatial

    mask, M = r.mask, len(imgs)
    px = imgs[:, mask].astype(float) - r.truth.image[mask].astype(float)
    se = np.mean(px * px, axis=-1)
    samples = np.stack([se, se / (1 + se), se**0.5], axis=1)  # (M, 3, P): RMSE, relMSE, FLIP
    refs = [
        np.asarray(a)[mask] for a in (r.truth.image, r.truth.noise, r.oracle, r.oracle_seed, r.oracle_coarse)
    ]
    t = split.pixel_terms(imgs[:, mask], *refs, r.held_px[mask])
    h = r.held_px[mask]
    parts = [[np.broadcast_to(v, se.shape)[i] for v in t.values()] + [t["total"][i] * h, t["total"][i] * ~h]
             for i in range(M)]  # fmt: skip
    rng = np.random.default_rng(1)
    pix = np.repeat(np.flatnonzero(mask), 4)
    field = ndimage.gaussian_filter(rng.normal(size=(M, *mask.shape)), (0, 3, 3))[:, mask]
    flags = np.repeat(field > 0.1, 4, axis=1)[:, None] & (rng.random((M, 5, pix.size)) < 0.7)
    hidden = np.repeat(rng.random(mask.sum()) < 0.2, 4)
    angle = np.repeat(np.abs(field), 4, axis=1) + rng.random((M, pix.size))

    def new_pixels():
        return [ci for ci, _ in spatial.grouped_intervals(list(samples), mask, 0.95)]

    def rays(mod):
        out = []
        for f, a in zip(flags, angle):
            row = mod.fraction_intervals(f, pix, mask.shape, 0.95)[0]
            for sel in (~hidden, hidden):
                row += mod.fraction_intervals(f[:1, sel], pix[sel], mask.shape, 0.95)[0]
            out.append(row + [mod.quantile_interval(a, p, pix, mask.shape, 0.95) for p in (50, 95)])
        return out

    return [
        ("pixel intervals (RMSE, relMSE, FLIP)", lambda: [old.mean_intervals(x, mask, 0.95)[0] for x in samples],
         new_pixels),
        ("the split's intervals (10 terms)", lambda: [old.mean_intervals(x, mask, 0.95)[0] for x in parts],
         lambda: [ci for ci, _ in spatial.grouped_intervals(parts, mask, 0.95)]),
        ("exposed relMSE's interval", lambda: [old.mean_intervals([x], mask, 0.95)[0] for x in se],
         lambda: [ci for ci, _ in spatial.grouped_intervals(se[:, None], mask, 0.95)]),
        ("ray intervals (5 fractions, visible, hidden, 2 percentiles)", lambda: rays(old), lambda: rays(spatial)),
    ]  # fmt: skip


def bench_spatial(n: int, methods: int, before: str, repeats: int = 3):
    """ms per method row of each group of spatial intervals, before (``before``'s spatial.py) and now, in one run,
    CPU time (all threads), the fastest of ``repeats`` (the caches emptied before each, as at a case's start), their
    values compared."""
    from study.stats import region, spatial

    old = _module_at(before, "study/stats/spatial.py")
    r, imgs = frame(n, methods, np.random.default_rng(0))
    rows = []
    for name, a_fn, b_fn in spatial_groups(r, imgs, old):
        b_fn()  # libraries loaded
        best, outs = [np.inf, np.inf], [None, None]
        for _ in range(repeats):  # the fastest of a few (a shared host's load varies between runs)
            for j, fn in enumerate((a_fn, b_fn)):
                region._KEPT.clear()
                spatial._MEASURED.clear()
                t0 = (
                    time.process_time()
                )  # CPU seconds (both FFT threads): steadier than the wall on a shared host
                outs[j] = fn()
                best[j] = min(best[j], time.process_time() - t0)
        same = outs[0] == outs[1]
        rows.append((name, best[0] / methods * 1e3, best[1] / methods * 1e3, same))
        print(
            f"spatial {name}: {rows[-1][1]:.0f} → {rows[-1][2]:.0f} ms per row (identical: {same})",
            flush=True,
        )
    return rows


def _same(a, b) -> float:
    """The largest relative difference of two lists of column dicts (0: equal)."""
    worst = 0.0
    for x, y in zip(a, b):
        for k in set(x) & set(y):
            u, v = x[k], y[k]
            if isinstance(u, float) and isinstance(v, float) and np.isfinite(u) and np.isfinite(v):
                worst = max(worst, abs(u - v) / max(abs(u), abs(v), 1e-30))
    return worst


def bench(backend: str, n: int, methods: int):
    rng = np.random.default_rng(0)
    r, imgs = frame(n, methods, rng)
    rows = []
    for name, old, new in groups(r, imgs, backend):
        new()  # kernels traced, libraries loaded
        t0 = time.perf_counter()
        a = old()
        t1 = time.perf_counter()
        b = new()
        t2 = time.perf_counter()
        rows.append((name, (t1 - t0) / methods * 1e3, (t2 - t1) / methods * 1e3, _same(a, b)))
        print(f"{backend} {name}: {rows[-1][1]:.0f} → {rows[-1][2]:.0f} ms per row (diff {rows[-1][3]:.1e})",
              flush=True)  # fmt: skip
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backends", nargs="+", default=["numpy", "llvm"])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--methods", type=int, default=4)
    ap.add_argument("--out", default=str(REPORT))
    ap.add_argument(
        "--spatial-before",
        metavar="REV",
        help="time only the spatial intervals, REV's study/stats/spatial.py beside today's (prints)",
    )
    args = ap.parse_args(argv)
    if args.spatial_before:
        rows = bench_spatial(args.size, args.methods, args.spatial_before)
        print(
            f"\nms per {args.size}² method row, {args.methods} methods, {os.cpu_count()} CPU cores, load "
            f"{os.getloadavg()[0]:.1f}: spatial intervals at {args.spatial_before} | now | values identical"
        )
        for name, a, b, same in rows:
            print(f"| {name} | {a:.0f} | {b:.0f} | {same} |")
        return
    from study import runtime
    from study.codehash import code_hash
    from study.measure import batched

    if any(b != "numpy" for b in args.backends):
        runtime.require()
    table = {be: bench(be, args.size, args.methods) for be in args.backends}
    names = [row[0] for row in next(iter(table.values()))]
    head = "| column group | " + " | ".join(f"{be} before ms | {be} batched ms" for be in table) + " |"
    lines = [head, "|---|" + "---:|---:|" * len(table)]
    for i, name in enumerate(names):
        cells = " | ".join(f"{table[be][i][1]:.0f} | {table[be][i][2]:.0f}" for be in table)
        lines.append(f"| {name} | {cells} |")
    tot = " | ".join(f"**{sum(r[1] for r in table[be]):.0f}** | **{sum(r[2] for r in table[be]):.0f}**"
                     for be in table)  # fmt: skip
    lines.append(f"| all image columns of one method row | {tot} |")
    worst = max(r[3] for rows in table.values() for r in rows)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    text = "\n".join([
        f"ms per {args.size}² method row, {args.methods} method images stacked, each column group timed once per "
        f"path in one run ({os.cpu_count()} CPU cores, load average {load:.1f} at the end; code "
        f"{code_hash(batched)}); *before*: the per-method path (one image at a time, FLIP over the whole frame), "
        f"*batched*: study/measure/batched.py. Largest relative difference between the two paths' values: "
        f"{worst:.1e}. Made by `PYTHONPATH=. .venv/bin/python scripts/bench_columns.py "
        f"--backends {' '.join(args.backends)} --size {args.size} --methods {args.methods}`.",
        "",
        *lines,
    ])  # fmt: skip
    print(text)
    if not args.out:
        return
    out = Path(args.out)
    if out.resolve() == REPORT.resolve():
        doc = out.read_text()
        if BEGIN in doc and END in doc:
            a, rest = doc.split(BEGIN, 1)
            doc = a + BEGIN + "\n" + text + "\n" + END + rest.split(END, 1)[1]
        else:
            doc = doc.replace("## Caveats", f"## Image columns per method row (issue 52)\n\n{BEGIN}\n{text}\n{END}\n\n"
                              "## Caveats")  # fmt: skip
        out.write_text(doc)
    else:
        out.write_text(f"# Image columns per method row\n\n{text}\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
