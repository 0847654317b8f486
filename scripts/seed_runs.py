"""Many short runs of one glossy case (Celarek et al. 2019; study.measure.seeds): E[MSE] and Var[MSE] over seeds of
the ``stochastic`` method, the glossy truth (truth_at_hit: the GGX lobe path traced) and Mitsuba's render of the
rough conductor, and a per-tile Welch t-test between the truth and Mitsuba (Jung et al. 2020) with the histogram
of its p-values. Writes reports/calibration/seed_runs.md and reports/calibration/welch_pvalues.png (a few minutes
on one core: one case at 48², 16 samples, per seed).

    PYTHONPATH=. .venv/bin/python scripts/seed_runs.py [--seeds 16] [--out reports/calibration] [--cache .cache]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from study.api import load_scene, method_list
from study.cache import Cache
from study.measure import seeds as sd
from study.measure.case import run_case

#: The case: fig_glossy's α = 0.15 sphere near the reference point, small and cheap.
CASE = {
    "camera.width": 48,
    "camera.height": 48,
    "camera.frame_object": True,
    "render.supersample": 1,
    "render.cube_res": 32,
    "render.cube_spp": 8,
    "render.spp": 16,
    "object.alpha": 0.15,
    "object.center": [0.6, 1.2, 0.3],
}
SAMPLES = 16  # stochastic's GGX samples per ray


def runs(n: int, cache: str | None) -> dict[str, np.ndarray]:
    """(n, H, W, 3) images per name (stochastic, truth, mitsuba) at render seeds 0 … n − 1 (stochastic's samples
    seeded alike), and the object's pixels ``mask``."""
    out = {"stochastic": [], "truth": [], "mitsuba": []}
    for s in range(n):
        t0 = time.time()
        scene = load_scene("scenes/room.toml", {**CASE, "render.seed": s})
        c = run_case(scene, method_list([f"stochastic(samples={SAMPLES}, seed={s})"]), cache=Cache(cache),
                     keep_images=True, intervals=False)  # fmt: skip
        (img,) = c.images.values()
        for k, v in (("stochastic", img), ("truth", c.truth), ("mitsuba", c.mitsuba)):
            out[k].append(np.asarray(v, float))
        mask = np.asarray(c.mask, bool)
        print(f"seed {s}: {time.time() - t0:.0f} s", flush=True)
    return {k: np.stack(v) for k, v in out.items()} | {"mask": mask}


def table(r: dict[str, np.ndarray]) -> list[tuple[str, str, dict]]:
    m, mse = r["mask"], sd.mse_over_seeds
    return [
        ("stochastic", "the truth's mean over the seeds", mse(r["stochastic"], r["truth"].mean(0), m)),
        ("stochastic", "Mitsuba's mean over the seeds", mse(r["stochastic"], r["mitsuba"].mean(0), m)),
        ("truth (glossy, two seeds)", "its other seeds' mean", mse(r["truth"], None, m)),
        ("Mitsuba (two seeds)", "its other seeds' mean", mse(r["mitsuba"], None, m)),
        ("Mitsuba (two seeds)", "the truth's mean over the seeds", mse(r["mitsuba"], r["truth"].mean(0), m)),
    ]  # fmt: skip


def figure(p: np.ndarray, diff: np.ndarray, path: Path, title: str) -> None:
    """The p-values' histogram against the uniform, their map, and the mean difference Mitsuba − truth."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b, c) = plt.subplots(1, 3, figsize=(12, 3.6))
    v = p[np.isfinite(p)]
    a.hist(v, bins=20, range=(0, 1), color="#4477aa", edgecolor="white")
    a.axhline(v.size / 20, color="k", ls="--", lw=1, label="uniform (no difference)")
    a.set_xlabel("Welch p-value per 2 × 2 tile")
    a.set_ylabel("tiles")
    a.legend(fontsize=8)
    for ax, img, kw, name in (
        (b, p, {"vmin": 0, "vmax": 1, "cmap": "viridis"}, "p-value per tile (white: off the object)"),
        (
            c,
            diff,
            {"cmap": "RdBu_r", "norm": _centred(diff)},
            "mean Mitsuba − truth (scale: 90th pct of |·|)",
        ),
    ):
        im = ax.imshow(img, interpolation="nearest", **kw)
        ax.set_title(name, fontsize=9)
        ax.axis("off")
        fig.colorbar(im, ax=ax, fraction=0.046)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _centred(img: np.ndarray):
    from matplotlib.colors import TwoSlopeNorm

    m = float(np.nanpercentile(np.abs(img), 90)) if np.isfinite(img).any() else 1.0  # the highlight saturates
    return TwoSlopeNorm(0.0, -max(m, 1e-9), max(m, 1e-9))


def _outside_highlight(r: dict[str, np.ndarray], p: np.ndarray) -> tuple[int, float, float, float]:
    """(tiles outside the highlight, the highlight's share of the squared mean difference, the share of the other
    tiles below 0.05, their median mean difference Mitsuba − truth)."""
    d, whole = sd.tiles((r["mitsuba"].mean(0) - r["truth"].mean(0))[None], r["mask"])
    d = d[0].mean(-1)[whole]
    hot = np.abs(d) > 0.1 * np.abs(d).max()
    pw = p[whole]
    return (
        int((~hot).sum()),
        float((d[hot] ** 2).sum() / (d**2).sum()),
        float(np.mean(pw[~hot] < 0.05)),
        float(np.median(d[~hot])),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--out", default="reports/calibration", type=Path)
    ap.add_argument("--cache", default=".cache")
    a = ap.parse_args()
    r = runs(a.seeds, a.cache)
    p = sd.welch_map(r["truth"], r["mitsuba"], r["mask"])
    ks = sd.uniformity(p)
    low = float(np.mean(p[np.isfinite(p)] < 0.05))
    a.out.mkdir(parents=True, exist_ok=True)
    diff = np.where(r["mask"], (r["mitsuba"].mean(0) - r["truth"].mean(0)).mean(-1), np.nan)
    figure(p, diff, a.out / "welch_pvalues.png", f"glossy truth vs Mitsuba, {a.seeds} seeds each: KS p = {ks:.2g}, "
           f"{100 * low:.0f} % of tiles below 0.05")  # fmt: skip
    lines = [
        "# Many short runs: error over seeds, and the truth against Mitsuba",
        "",
        f"Written by `python scripts/seed_runs.py --seeds {a.seeds}` (`study/measure/seeds.py`): one glossy case "
        f"(α = 0.15 sphere near the reference point, {CASE['camera.width']}², {CASE['render.spp']} samples, "
        f"`stochastic(samples={SAMPLES})`) at render seeds 0 … {a.seeds - 1}; each truth and Mitsuba image is "
        "itself the mean of two renders (seeds s and s + 7919). MSE over the object's "
        f"{int(r['mask'].sum())} pixels, linear RGB; *variance*: the mean per-pixel variance over the seeds, "
        "*bias²*: what the seeds' mean still differs by, less the variance left in it (Celarek et al. 2019).",
        "",
        "| image | against | E[MSE] | sd[MSE] | variance | bias² |",
        "|---|---|---|---|---|---|",
    ]
    for name, ref, v in table(r):
        lines.append(f"| {name} | {ref} | {v['mse_mean']:.3g} | {v['mse_var'] ** 0.5:.2g} | {v['variance']:.3g} "
                     f"| {v['bias2']:.3g} |")  # fmt: skip
    far, share, rest, sign = _outside_highlight(r, p)
    lines += [
        "",
        f"Welch's t-test per 2 × 2 tile, truth vs Mitsuba ({int(np.isfinite(p).sum())} tiles, "
        f"[welch_pvalues.png](welch_pvalues.png)): Kolmogorov–Smirnov p = {ks:.3g} against uniform p-values; "
        f"{100 * low:.1f} % of tiles below 0.05 (5 % if the two agreed). The tiles where Mitsuba − truth exceeds "
        f"a tenth of its largest value (the point light's highlight, which the truth leaves out) hold "
        f"{100 * share:.0f} % of the squared difference; the other {far} tiles are still below 0.05 in "
        f"{100 * rest:.0f} % of cases, Mitsuba {'darker' if sign < 0 else 'brighter'} there by a median "
        f"{abs(sign):.3g} (the object's shadow and interreflection, one bounce more on the reflected path).",
        "",
    ]
    (a.out / "seed_runs.md").write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
