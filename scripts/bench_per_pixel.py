"""Time ObjectRays.per_pixel, shading.composite and outcomes.majority against their previous versions (copied
below as they were before the P-pixel rewrite) on a disc covering ~30 % of the frame, and assert that the outputs
are bit-identical (same dtype, shape, NaNs and float bits).

    PYTHONPATH=. python scripts/bench_per_pixel.py [--repeat 5]

Prints one line per (function, image, S, value shape): old ms, new ms (best of ``--repeat`` timeit runs), ratio.
"""

from __future__ import annotations

import argparse
import timeit
import warnings
from functools import partial

import numpy as np

from study.measure import outcomes
from study.optics import shading


# ------------------------------------------------------------------ the previous versions, verbatim in substance
def old_per_pixel(self: shading.ObjectRays, values, fill=np.nan, reduce="mean"):
    H, W, S = self.hit.shape
    values = self.per_camera_ray(values)
    if S == 1:
        out = np.full((H, W) + values.shape[1:], np.nan)
        out[self.hit[..., 0]] = values
        return np.where(np.isnan(out), fill, out)
    if reduce == "mean":
        ok = ~np.isnan(values)
        tot = np.zeros((H, W, S) + values.shape[1:])
        cnt = np.zeros(tot.shape, np.intp)
        tot[self.hit], cnt[self.hit] = np.where(ok, values, 0.0), ok
        with np.errstate(invalid="ignore", divide="ignore"):
            red = np.sum(tot, axis=2) / np.sum(cnt, axis=2)
        return np.where(np.isnan(red), fill, red)
    out = np.full((H, W, S) + values.shape[1:], np.nan)
    out[self.hit] = values
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        red = np.nanmean(out, axis=2) if reduce == "mean" else np.nanmax(out, axis=2)
    return np.where(np.isnan(red), fill, red)


def old_composite(rays: shading.ObjectRays, reflected, background):
    H, W, S = rays.hit.shape
    sub = np.broadcast_to(background[:, :, None, :], (H, W, S, 3)).copy()
    sub[rays.hit] = rays.per_camera_ray(reflected, total=True)
    return sub.mean(axis=2).astype(np.float32)


def old_majority(fractions):
    f = np.asarray(fractions, float)
    best, top = np.full(f.shape[:-1], 3.0), np.nan_to_num(f[..., 3])
    for c in (2, 1, 0):
        v = np.nan_to_num(f[..., c])
        best[v > top] = c
        top = np.maximum(top, v)
    return np.where(top > 0, best, np.nan)


# ------------------------------------------------------------------ inputs
def disc_hits(H: int, W: int, S: int, rng, cover: float = 0.3) -> np.ndarray:
    """(H, W, S) bool: stratified jittered sub-pixel rays inside a centred disc of area ``cover`` × frame."""
    n = int(round(np.sqrt(S)))
    j, i = np.meshgrid(np.arange(W), np.arange(H))
    sy, sx = np.divmod(np.arange(S), n)
    x = j[..., None] + (sx + rng.random((H, W, S))) / n
    y = i[..., None] + (sy + rng.random((H, W, S))) / n
    r2 = cover * H * W / np.pi
    return (x - W / 2) ** 2 + (y - H / 2) ** 2 < r2


def ray_values(rng, M: int, tail: tuple, nan: float = 0.05) -> np.ndarray:
    v = rng.random((M,) + tail) * 10.0 ** rng.integers(-2, 3, (M,) + (1,) * len(tail))
    v[rng.random(v.shape) < nan] = np.nan
    return v


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Same dtype, shape, NaN positions and float bits (NaNs compared by position, the rest by bit pattern)."""
    if a.dtype != b.dtype or a.shape != b.shape or not np.array_equal(a, b, equal_nan=True):
        return False
    na, nb = np.isnan(a), np.isnan(b)
    u = {4: np.uint32, 8: np.uint64}[a.dtype.itemsize]
    return bool(np.array_equal(na, nb) and np.array_equal(a[~na].view(u), b[~nb].view(u)))


def best_ms(f, repeat: int) -> float:
    number = 1
    while min(timeit.repeat(f, number=number, repeat=1)) < 0.05 and number < 64:
        number *= 2
    return min(timeit.repeat(f, number=number, repeat=repeat)) / number * 1e3


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(2024)
    rows = []

    def row(name, old, new, *args, **kw):
        old, new = partial(old, *args, **kw), partial(new, *args, **kw)
        o, n = old(), new()
        assert same_bits(o, n), f"{name}: outputs differ"
        t_old, t_new = best_ms(old, a.repeat), best_ms(new, a.repeat)
        rows.append((name, t_old, t_new))
        print(f"{name:<44s} {t_old:9.2f} ms {t_new:9.2f} ms  ×{t_old / t_new:5.1f}", flush=True)

    print(f"{'function  image  S  values':<44s} {'old':>12s} {'new':>12s}  ratio")
    for H, S in ((256, 9), (1024, 1), (1024, 4)):
        hit = disc_hits(H, H, S, rng)
        M = int(hit.sum())
        z = np.zeros((M, 3))
        rays = shading.ObjectRays(hit, z, z, z, z)
        tag = f"{H}² S={S}"
        for tail in ((), (3,), (4,)):
            v = ray_values(rng, M, tail)
            shape = "(M" + "".join(f", {t}" for t in tail) + ")"
            row(f"per_pixel mean {tag} {shape}", old_per_pixel, shading.ObjectRays.per_pixel, rays, v)
            if S > 1:
                row(
                    f"per_pixel max  {tag} {shape}",
                    old_per_pixel,
                    shading.ObjectRays.per_pixel,
                    rays,
                    v,
                    fill=0.0,
                    reduce="max",
                )
        for dt in (np.float32, np.float64):
            bg = rng.random((H, H, 3)).astype(dt)
            refl = rng.random((M, 3))
            row(f"composite {tag} bg {np.dtype(dt).name}", old_composite, shading.composite, rays, refl, bg)
        cls = rng.integers(0, 4, M)
        frac = rays.per_pixel((cls[:, None] == np.arange(4)).astype(float), fill=np.nan)
        row(f"majority {tag}", old_majority, outcomes.majority, frac)
    old_total, new_total = sum(r[1] for r in rows), sum(r[2] for r in rows)
    print(f"{'all rows':<44s} {old_total:9.2f} ms {new_total:9.2f} ms  ×{old_total / new_total:5.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
