"""Figures like the paper's: image grids with error heatmaps, and the metrics CSV behind them."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from study.cache import Cache
from study.errors import StudyError
from study.evaluate.case import CaseOutput, run_case
from study.evaluate.metrics import to_ldr
from study.harness.config import load_figure_config
from study.harness.runner import metadata
from study.io import atomic_savefig, atomic_write
from study.tables import write_csv


def _crop_box(mask: np.ndarray, margin: float = 0.35) -> tuple[slice, slice]:
    """A square around the object's pixels, with a margin, inside the image."""
    ys, xs = np.nonzero(mask)
    H, W = mask.shape
    if ys.size == 0:
        return slice(0, H), slice(0, W)
    cy, cx = (ys.min() + ys.max()) / 2, (xs.min() + xs.max()) / 2
    half = max(ys.max() - ys.min(), xs.max() - xs.min()) / 2 * (1 + margin) + 2
    half = min(half, H / 2, W / 2)
    y0 = int(np.clip(cy - half, 0, H - 2 * half)); x0 = int(np.clip(cx - half, 0, W - 2 * half))
    return slice(y0, y0 + int(2 * half)), slice(x0, x0 + int(2 * half))


def image_grid(cases: list[CaseOutput], labels: list[str], path: Path, *, title: str,
               occlusion_panel: bool = False, row_labels: list[str] | None = None) -> None:
    """Rows: cases; columns: each method's image, the ray-traced (Mitsuba) image, each method's angular-error
    heatmap (degrees, log scale 0.01°–30°) and, with ``occlusion_panel``, the fraction of each pixel's rays whose
    exact hit is hidden from the reference point. Images are tone mapped by clipping at 1 and sRGB encoding."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    ncol = 2 * len(labels) + 1 + int(occlusion_panel)
    fig, axes = plt.subplots(len(cases), ncol, figsize=(2.3 * ncol, 2.3 * len(cases) + 0.6), squeeze=False)
    norm = LogNorm(vmin=0.01, vmax=30)
    hm = None
    for r, case in enumerate(cases):
        sy, sx = _crop_box(case.mask | (case.occluded > 0))
        panels = [(lab, to_ldr(case.images[lab])) for lab in labels] + [("ray traced (Mitsuba)", to_ldr(case.mitsuba))]
        for c, (lab, img) in enumerate(panels):
            axes[r, c].imshow(img[sy, sx], interpolation="nearest")
            if r == 0:
                axes[r, c].set_title(lab, fontsize=8)
        for k, lab in enumerate(labels):
            ax = axes[r, len(labels) + 1 + k]
            err = np.clip(case.angle_maps[lab][sy, sx], 0.01, None)
            hm = ax.imshow(err, norm=norm, cmap="magma", interpolation="nearest")
            if r == 0:
                ax.set_title(f"angle error: {lab}", fontsize=8)
        if occlusion_panel:
            ax = axes[r, -1]
            occ = np.where(case.mask | (case.occluded > 0), case.occluded, np.nan)[sy, sx]
            ax.imshow(occ, vmin=0, vmax=1, cmap="viridis", interpolation="nearest")
            if r == 0:
                ax.set_title("hidden from reference point", fontsize=8)
        cx, cy, cz = case.scene.object.center
        axes[r, 0].set_ylabel(row_labels[r] if row_labels else f"({cx:g}, {cy:g}, {cz:g})", fontsize=8)
        for ax in axes[r]:
            ax.set_xticks([]); ax.set_yticks([])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 0.93, 1))
    if hm is not None:
        cax = fig.add_axes((0.94, 0.15, 0.012, 0.7))
        fig.colorbar(hm, cax=cax, label="angular error (deg)")
    atomic_savefig(fig, path, dpi=110)


def figure_positions(config: str | Path, out: str | Path, *, name: str, backend: str = "numpy",
                     cache: str | Path | None = ".cache", progress=None) -> list[dict]:
    """Run every position (or case) of a figure config with every method; write ``<out>/<name>.png`` and
    ``<out>/metrics.csv`` (one row per position or case × method). Returns the rows."""
    cfg, scene, methods = load_figure_config(config)
    by_name = {m.name: m.label for m in reversed(methods)}           # a bare name means its first entry
    labels = [g if g in {m.label for m in methods} else by_name.get(g, g) for g in cfg.grid] if cfg.grid else \
        [m.label for m in methods]
    unknown = [g for g in labels if g not in {m.label for m in methods}]
    if unknown:
        raise StudyError(f"grid names {unknown[0]!r}, which is not among the methods "
                         f"({', '.join(m.label for m in methods)})", file=str(config), key="grid")
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise StudyError(f"cannot create the output directory ({err.strerror})", file=str(out)) from None
    store = Cache(cache)
    cases, rows = [], []
    todo = cfg.case_list()
    for i, (suffix, _, over) in enumerate(todo):
        t0 = time.perf_counter()
        sc = scene.with_updates(over, source=str(config))
        case = run_case(sc, methods, backend=backend, cache=store, case_id=f"{name}-{suffix}")
        for r in case.rows:
            r["case_seconds"] = time.perf_counter() - t0
        cases.append(case)
        rows += case.rows
        if progress:
            progress(i + 1, len(todo))
    write_csv(rows, out / "metrics.csv")
    meta = metadata(config, backend=backend, seed=scene.render.seed, methods=[m.label for m in methods],
                    cases=len(todo), figure=name)
    atomic_write(out / "metadata.json", json.dumps(meta, indent=2).encode())
    image_grid(cases, labels, out / f"{name}.png", title=f"{name}: {scene.room.min}..{scene.room.max} room, "
               f"reference point {list(scene.reference.point)}, cube {scene.render.cube_res}², backend {backend}",
               occlusion_panel=cfg.occlusion_panel,
               row_labels=None if cfg.positions is not None else [lab for _, lab, _ in todo])
    return rows
