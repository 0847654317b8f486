"""Figures like the paper's: image grids with error heatmaps, and the metrics table behind them.

A figure's files (``<name>.png``, ``metrics.csv`` and ``metrics.parquet``, ``metadata.json``, and per case its EXRs
under ``exr/<case>/`` and the report viewer's images under ``viewer/``, :mod:`study.outputs.viewer`) are one output
set (:func:`study.io.output_set`): written when every case is done and swapped in together, so a failed or killed
run leaves the previous figure as it was. Every case is checked (:mod:`study.harness.budget`) before any runs.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from study.cache import Cache
from study.errors import StudyError
from study.harness import budget
from study.harness.config import load_figure_config
from study.harness.runner import metadata
from study.io import atomic_savefig, json_text, locked, output_set, png_bytes
from study.measure.case import CaseOutput, run_case
from study.measure.metrics import to_ldr
from study.measure.outcomes import NAMES as OUTCOME_NAMES
from study.outputs import viewer
from study.outputs.viewer import OUTCOME_COLORS
from study.outputs.viewer import crop_box as _crop_box
from study.scene.environment import describe
from study.tables import table_files


def _wrap(label: str) -> str:
    """A method label on two lines (name, then its parameters), so that panel titles do not run into each other."""
    return label.replace("(", "\n(", 1)


def _outcome_legend(fig, first, last) -> None:
    """The outcome classes' legend, centred under the outcome columns (axes ``first`` … ``last`` of the last row)."""
    from matplotlib.patches import Patch

    a, b = first.get_position(), last.get_position()
    handles = [Patch(facecolor=c, edgecolor="0.4", label=n) for c, n in zip(OUTCOME_COLORS, OUTCOME_NAMES)]
    fig.legend(
        handles=handles,
        loc="upper center",
        ncol=4,
        fontsize=8,
        frameon=False,
        bbox_to_anchor=((a.x0 + b.x1) / 2, a.y0 - 0.01),
        title="outcome per pixel: most frequent class of its rays (ε = max(1 cm, one texel at the hit))",
        title_fontsize=8,
    )


def image_grid(
    cases: list[CaseOutput],
    labels: list[str],
    path: Path | None,
    *,
    title: str,
    occlusion_panel: bool = False,
    outcome_panel: bool = False,
    row_labels: list[str] | None = None,
) -> bytes | None:
    """Rows: cases; columns: each method's image, the ray-traced (Mitsuba) image, each method's angular-error
    heatmap (degrees, log scale 0.01°–30°), with ``outcome_panel`` each method's outcome-class map (per pixel the
    most frequent class of its rays: correct / wrong depth / wrong surface / no hit, :mod:`study.measure.outcomes`)
    and, with ``occlusion_panel``, the fraction of each pixel's rays whose exact hit is hidden from the reference
    point. Images are tone mapped by clipping at 1 and sRGB encoding. With ``path`` None: the PNG's bytes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm

    n_out = len(labels) if outcome_panel else 0
    ncol = 2 * len(labels) + 1 + n_out + int(occlusion_panel)
    legend_h = 0.5 if outcome_panel else 0.0  # inches under the grid for the outcome legend
    height = 2.3 * len(cases) + 0.6 + legend_h
    fig, axes = plt.subplots(len(cases), ncol, figsize=(2.3 * ncol, height), squeeze=False)
    ocmap = ListedColormap(OUTCOME_COLORS).with_extremes(bad="white")
    onorm = BoundaryNorm(np.arange(-0.5, 4), ocmap.N)
    norm = LogNorm(vmin=0.01, vmax=30)
    hm = None
    for r, case in enumerate(cases):
        sy, sx = _crop_box(case.mask | (case.occluded > 0))
        panels = [(lab, to_ldr(case.images[lab])) for lab in labels] + [
            ("ray traced (Mitsuba)", to_ldr(case.mitsuba))
        ]
        for c, (lab, img) in enumerate(panels):
            axes[r, c].imshow(img[sy, sx], interpolation="nearest")
            if r == 0:
                axes[r, c].set_title(_wrap(lab), fontsize=8)
        for k, lab in enumerate(labels):
            ax = axes[r, len(labels) + 1 + k]
            err = np.clip(case.angle_maps[lab][sy, sx], 0.01, None)
            hm = ax.imshow(err, norm=norm, cmap="magma", interpolation="nearest")
            if r == 0:
                ax.set_title(f"angle error: {_wrap(lab)}", fontsize=8)
        for k, lab in enumerate(labels[:n_out]):
            ax = axes[r, 2 * len(labels) + 1 + k]
            ax.imshow(case.outcome_maps[lab][sy, sx], cmap=ocmap, norm=onorm, interpolation="nearest")
            if r == 0:
                ax.set_title(f"outcome: {_wrap(lab)}", fontsize=8)
        if occlusion_panel:
            ax = axes[r, -1]
            occ = np.where(case.mask | (case.occluded > 0), case.occluded, np.nan)[sy, sx]
            ax.imshow(occ, vmin=0, vmax=1, cmap="viridis", interpolation="nearest")
            if r == 0:
                ax.set_title("hidden from\nreference point", fontsize=8)
        cx, cy, cz = case.scene.object.center
        axes[r, 0].set_ylabel(row_labels[r] if row_labels else f"({cx:g}, {cy:g}, {cz:g})", fontsize=8)
        for ax in axes[r]:
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle(title, fontsize=10)
    w = fig.get_figwidth()  # the colour bar and its label: 1.1 in on the right, any width
    fig.tight_layout(rect=(0, legend_h / height, 1 - 1.1 / w, 1))
    if outcome_panel:
        _outcome_legend(fig, axes[-1, 2 * len(labels) + 1], axes[-1, 2 * len(labels) + n_out])
    if hm is not None:
        cax = fig.add_axes((1 - 0.95 / w, 0.15, 0.14 / w, 0.7))
        fig.colorbar(hm, cax=cax, label="angular error (deg)")
    if path is None:
        return png_bytes(fig, dpi=110)
    atomic_savefig(fig, path, dpi=110)
    return None


def run_config_case(scene, methods, *, backend: str, cache, case_id: str, where: str):
    """:func:`run_case` for one row of a config; a refusal that names no file is blamed on ``where`` (the config
    and the row, e.g. ``configs/fig4.toml positions[2]``)."""
    try:
        return run_case(scene, methods, backend=backend, cache=cache, case_id=case_id)
    except StudyError as err:
        if err.file:
            raise
        raise type(err)(err.detail, file=where, key=err.key, code=err.code) from None


def figure_positions(
    config: str | Path,
    out: str | Path,
    *,
    name: str,
    backend: str = "numpy",
    cache: str | Path | None = ".cache",
    progress=None,
) -> list[dict]:
    """Run every position (or case) of a figure config with every method; write ``<out>/<name>.png`` and
    ``<out>/metrics.csv`` (one row per position or case × method). Returns the rows."""
    cfg, scene, methods = load_figure_config(config)
    by_name = {m.name: m.label for m in reversed(methods)}  # a bare name means its first entry
    labels = (
        [g if g in {m.label for m in methods} else by_name.get(g, g) for g in cfg.grid]
        if cfg.grid
        else [m.label for m in methods]
    )
    unknown = [g for g in labels if g not in {m.label for m in methods}]
    if unknown:
        raise StudyError(
            f"grid names {unknown[0]!r}, which is not among the methods "
            f"({', '.join(m.label for m in methods)})",
            file=str(config),
            key="grid",
        )
    todo = cfg.case_list()
    what = "positions" if cfg.positions is not None else "cases"
    scenes = [(f"{name}-{suffix}", scene.with_updates(over, source=str(config))) for suffix, _, over in todo]
    budget.check_backend(backend)
    budget.check(scenes, methods, source=str(config))
    store = Cache(cache)
    with locked(out):  # one command at a time here; the files are written together at the end
        cases, rows = [], []
        for i, (case_id, sc) in enumerate(scenes):
            t0 = time.perf_counter()
            case = run_config_case(
                sc, methods, backend=backend, cache=store, case_id=case_id, where=f"{config} {what}[{i}]"
            )
            for r in case.rows:
                r["case_seconds"] = time.perf_counter() - t0
            cases.append(case)
            rows += case.rows
            if progress:
                progress(i + 1, len(todo))
        meta = metadata(
            config,
            backend=backend,
            seed=scene.render.seed,
            methods=[m.label for m in methods],
            cases=len(todo),
            figure=name,
        )
        png = image_grid(
            cases,
            labels,
            None,
            title=f"{name}: {describe(scene)}, "
            f"reference point {list(scene.reference.point)}, cube {scene.render.cube_res}², "
            f"backend {backend}",
            occlusion_panel=cfg.occlusion_panel,
            outcome_panel=cfg.outcome_panel,
            row_labels=None if cfg.positions is not None else [lab for _, lab, _ in todo],
        )
        files = {
            **table_files(rows, "metrics"),
            "metadata.json": json_text(meta, indent=2),
            f"{name}.png": png,
        }
        every = [m.label for m in methods]
        titles = [None] * len(todo) if cfg.positions is not None else [lab for _, lab, _ in todo]
        with output_set(out, [*files, "exr", "viewer"], lock=False) as tmp:
            for rel, data in files.items():
                (tmp / rel).write_bytes(data.encode() if isinstance(data, str) else data)
            viewer.write_manifest(
                tmp,
                name,
                [
                    viewer.write_case(tmp, name, cid, case, every, title=t or "")
                    for (cid, _), case, t in zip(scenes, cases, titles)
                ],
            )
    return rows
