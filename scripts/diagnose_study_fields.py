"""Why the pixel-RMSE and ray-fraction intervals are too wide on the mosaics of study's own error maps
(study.stats.calibration.STUDY_ROWS), in numbers: the spread of the estimate over the replicates against the
variance the lag window estimates from single draws, and the ensemble's own covariance summed over growing lags
(where its positive part ends and the negative lobe of the tiling begins).

    PYTHONPATH=. .venv/bin/python scripts/diagnose_study_fields.py [--replicates N] [--seed S] [--lattice]

``--lattice``: the copies on a lattice at a random offset (the mosaic until issue 53's second item) instead of
study.stats.fields.mosaic's independent places (dead leaves).

Per design it prints: the true variance of the mean over the disc (over the replicates), the mean of the lag
window's variance and its ratio to it, the mean flat reach of the window (px), and the cumulative sum of the
ensemble covariance (residuals about the known truth, their lag products averaged over the replicates) out to
radius r over the true variance: it reaches 1 at the largest r, and a peak above 1 at short r is what a window
of that reach reads; the lag window's variance with one fixed flat reach (the draws' median) for every draw
(against the reach each draw picks from its own correlogram); and the ensemble covariance under each draw's own
window with the bias its centring correction then expects."""

from __future__ import annotations

import argparse

import numpy as np
from scipy import stats as sps

from study.stats import fields, region, spatial


def lattice(rng, tile: np.ndarray, level) -> np.ndarray:
    """The former mosaic: the frame tiled on a lattice with copies of ``tile`` (turned, mirrored, ``level``-mapped),
    the lattice shifted by a uniform offset."""
    s = tile.shape[0]
    n = fields.SIZE // s + 2
    out = np.empty((n * s, n * s))
    for i in range(n):
        for j in range(n):
            t = np.rot90(tile, int(rng.integers(4)))
            out[i * s : (i + 1) * s, j * s : (j + 1) * s] = level(
                t[:, ::-1] if rng.random() < 0.5 else t, rng
            )
    oy, ox = rng.integers(s, size=2)
    return out[oy : oy + fields.SIZE, ox : ox + fields.SIZE]


def _edge(rng):
    f = fields.study_edge(rng)
    return f, np.ones_like(f), fields.EDGE_MSE


def _wrong(rng, rays: int = 4):
    p = sps.norm.cdf(fields.study_wrong_probit(rng))
    k = rng.binomial(rays, p).astype(float)
    return k, np.full_like(k, rays), fields.study_wrong_truth()


def diagnose(name, draw, replicates, seed, radii=(2, 4, 8, 12, 16, 22, 30, 44, 60, 80)):
    rng = np.random.default_rng(seed)
    mask = fields.disc()
    est, var, acc, flats = [], [], None, []
    reach_by_angle = spatial._reach_by_angle

    def spy(*a):  # the flat reach per direction of each draw's window
        flats.append(reach_by_angle(*a))
        return flats[-1]

    spatial._reach_by_angle = spy
    for _ in range(replicates):
        num, den, truth = draw(rng)
        r, v, _, _ = spatial.ratio_variance(num, den, mask)
        est.append(r)
        var.append(v)
        e = np.where(mask, num - truth * den, 0.0) / den[mask].sum()
        s = region.lag_sums(e[None])[0]
        acc = s if acc is None else acc + s
    spatial._reach_by_angle = reach_by_angle
    est, var = np.array(est), np.array(var)
    acc /= replicates
    reg = spatial.region(mask)
    n, R = reg.n, reg.reach
    cen = np.fft.fftshift(acc)  # lag 0 at the centre
    cy, cx = cen.shape[0] // 2, cen.shape[1] // 2
    cen = cen[cy - R : cy + R + 1, cx - R : cx + R + 1]
    inside, shares = [], []
    for (
        flat
    ) in flats:  # the ensemble covariance under each draw's own window, and the window's share of pairs
        w = np.clip(2.0 - reg.radii / flat[reg.bins], 0.0, 1.0)
        inside.append(float(np.sum(w * cen)))
        shares.append(float(np.sum(w * reg.pairs)) / (n * n))
    inside, shares = np.array(inside), np.array(shares)
    h, w = acc.shape
    dy = np.minimum(np.arange(h), h - np.arange(h))[:, None]
    dx = np.minimum(np.arange(w), w - np.arange(w))[None, :]
    rad = np.hypot(dy, dx)
    true = float(np.var(est))
    print(f"{name}: {replicates} draws, truth {truth:.4f}, mean estimate {est.mean():.4f}")
    print(
        f"  var of the mean over draws {true:.3g}; lag window's mean estimate {var.mean():.3g} "
        f"({var.mean() / true:.2f} ×, sd ratio {np.sqrt(var.mean() / true):.2f})"
    )
    print("  ensemble covariance summed to radius r, over the true variance:")
    print("   " + "  ".join(f"r≤{r}: {float(acc[rad <= r].sum()) / true:.2f}" for r in radii))
    print(f"   all lags: {float(acc.sum()) / true:.2f}")
    fixed = float(np.median([f.mean() for f in flats]))
    spatial._reach_by_angle = lambda *a: np.full(spatial.ANGLES, fixed)  # one window for every draw
    rng, again = np.random.default_rng(seed), []
    for _ in range(replicates):
        num, den, _ = draw(rng)
        again.append(spatial.ratio_variance(num, den, mask)[1])
    spatial._reach_by_angle = reach_by_angle
    print(
        f"  a fixed flat reach of {fixed:.1f} px for every draw: {np.mean(again) / true:.2f} × the variance"
    )
    print(
        f"  under each draw's own window (flat reach median {np.median([f.mean() for f in flats]):.1f} px): "
        f"{np.mean(inside) / true:.2f} × the variance; the window's share of the pairs {np.mean(shares):.2f}, so "
        f"the centring correction (Σ_w C − share·Σ C) / (1 − share) expects "
        f"{np.mean((inside / true - shares) / (1 - shares)):.2f} ×"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=400)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lattice", action="store_true")
    a = ap.parse_args()
    if a.lattice:
        fields.mosaic = lattice
    diagnose("RMSE² on the reflected-edge mosaic", _edge, a.replicates, a.seed)
    diagnose("ray fraction on the wrong-hit mosaic", _wrong, a.replicates, a.seed)


if __name__ == "__main__":
    main()
