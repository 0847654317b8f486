"""Figures like the paper's: image grids with error heatmaps, and the metrics table behind them.

A figure's files (``<name>.png``, and ``<name>-errors.png`` where one grid would be too wide for a page,
``metrics.csv`` and ``metrics.parquet``, ``metadata.json``, and per case its multi-layer EXR ``exr/<case>.exr`` and
the report viewer's images under ``viewer/``, :mod:`study.outputs.viewer`) are one output set
(:func:`study.io.write_set`): made in memory when every case is done, then written and swapped in together, so a
failed or killed run leaves the previous figure as it was. Every case is checked (:mod:`study.harness.budget`)
before any runs.
"""

from __future__ import annotations

import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from study import progress as pg
from study.cache import Cache
from study.errors import StudyError
from study.harness import budget, estimate
from study.harness.config import load_figure_config, plain_name, quality_overrides
from study.harness.runner import metadata
from study.io import atomic_savefig, file_stems, json_text, locked, png_bytes, write_set
from study.measure.case import CaseOutput, one_behind, start_case
from study.measure.metrics import to_ldr
from study.measure.outcomes import NAMES as OUTCOME_NAMES
from study.outputs import viewer
from study.outputs.case_images import image_choice
from study.outputs.viewer import HIDDEN_COLORS, HIDDEN_NAMES, OUTCOME_COLORS
from study.outputs.viewer import crop_box as _crop_box
from study.scene.environment import describe
from study.tables import table_files


def _wrap(label: str, width: int = 26) -> str:
    """A method label on lines of at most ``width`` characters where it can (name, then its parameters, broken
    after a comma), so that panel titles do not run into each other."""
    name, _, params = label.partition("(")
    if not params:
        return name
    lines, cur = [], "("
    for part in params.split(", "):
        if len(cur) > 1 and len(cur) + len(part) + 2 > width:
            lines.append(cur + ",")
            cur = part
        else:
            cur += (", " if len(cur) > 1 else "") + part
    return "\n".join([name, *lines, cur])


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


#: The widest grid PNG (pixels at 110 dpi) a page shows at full size; a wider figure is split (images, errors)
#: and its panels shrunk to fit.
MAX_WIDTH_PX = 1500
_DPI = 110


def _hidden_legend(fig, ax, binary: bool, im) -> None:
    """The hidden panel's own legend under it: two classes where each pixel is one ray (yes or no), else a small
    colour bar of the fraction — never the angular error's colour bar."""
    from matplotlib.patches import Patch

    p = ax.get_position()
    if binary:
        handles = [Patch(facecolor=c, edgecolor="0.4", label=n) for c, n in zip(HIDDEN_COLORS, HIDDEN_NAMES)]
        fig.legend(
            handles=handles,
            loc="upper center",
            fontsize=7,
            frameon=False,
            bbox_to_anchor=((p.x0 + p.x1) / 2, p.y0 - 0.01),
        )
    else:
        h = fig.get_size_inches()[1]  # placed in inches under the panel, whatever the figure's height
        cax = fig.add_axes((p.x0, p.y0 - 0.2 / h, p.width, 0.08 / h))
        fig.colorbar(im, cax=cax, orientation="horizontal", label="fraction of rays hidden")


def _rough(case: CaseOutput) -> bool:
    """A case whose object is rough (``object.alpha`` > 0): its reference panel is the lobe's truth_at_hit."""
    return case.scene.object.alpha > 0


def _template(
    labels: list[str], part: str, outcome_panel: bool, occlusion_panel: bool, per_row: int | None = None
) -> list[list[tuple]]:
    """The panels of one case, row by row, as (kind, label): ``all`` one row of everything; ``images`` the images;
    ``errors`` the angular errors, and under them the outcome maps and the hidden fraction. ``per_row``: each row
    wrapped onto rows of at most that many panels."""
    if per_row:
        tpl = _template(labels, part, outcome_panel, occlusion_panel)
        return [row[i : i + per_row] for row in tpl for i in range(0, len(row), per_row)]
    imgs = [("image", lab) for lab in labels] + [("mitsuba", None)]
    angle = [("angle", lab) for lab in labels]
    more = [("outcome", lab) for lab in labels] if outcome_panel else []
    more += [("hidden", None)] if occlusion_panel else []
    if part == "images":
        return [imgs]
    if part == "errors":
        return [angle, more] if more else [angle]
    return [imgs + angle + more]


# ---------------------------------------------------------------------------------------------- exposure
#: The exposure of a figure's images: the PERCENTILE-th percentile of the object's luminance in the reference
#: (Mitsuba's render, over the object's pixels of every case) is shown at WHITE, before clipping at 1 and sRGB.
PERCENTILE, WHITE = 99.0, 0.8
EXPOSURE_RULE = f"the {PERCENTILE:g}th percentile of the object's luminance in Mitsuba's render → {WHITE:g}"


def figure_exposure(cases: list[CaseOutput]) -> float:
    """The exposure (EV: images × 2^EV) of a figure's images, one for all its cases so rows compare:
    :data:`EXPOSURE_RULE` (Rec. 709 luminance); 0 where the object shows no light."""
    lum = [
        np.asarray(c.mitsuba, np.float64)[c.mask] @ np.array([0.2126, 0.7152, 0.0722])
        for c in cases
        if c.mitsuba is not None and c.mask is not None
    ]
    lum = np.concatenate(lum) if lum else np.zeros(0)
    lum = lum[np.isfinite(lum)]
    top = float(np.percentile(lum, PERCENTILE)) if lum.size else 0.0
    return float(np.log2(WHITE / top)) if top > 0 else 0.0


def image_grid(
    cases: list[CaseOutput],
    labels: list[str],
    path: Path | None,
    *,
    title: str,
    occlusion_panel: bool = False,
    outcome_panel: bool = False,
    row_labels: list[str] | None = None,
    part: str = "all",
    max_width_px: int | None = None,
    exposure: float = 0.0,
    wrap: bool = False,
) -> bytes | None:
    """Rows: cases; columns: each method's image, the ray-traced (Mitsuba) image (for a rough object the truth,
    :func:`study.measure.truth.lobe_at_hit`, as Mitsuba's camera render adds the point light's highlight), each
    method's angular-error heatmap (degrees, log scale 0.01°–30°), with ``outcome_panel`` each method's
    outcome-class map (per pixel the most frequent class of its rays: correct / wrong depth / wrong surface / no
    hit, :mod:`study.measure.outcomes`)
    and, with ``occlusion_panel``, the fraction of each pixel's rays whose exact hit is hidden from the reference
    point (two classes with a legend where each pixel is one ray). ``part``: ``"images"`` or ``"errors"`` (the
    angular errors, the outcome and hidden maps under them) for only those panels. Images are tone mapped by
    ``exposure`` (EV: × 2^exposure, :func:`figure_exposure`), clipping at 1 and sRGB encoding. ``max_width_px``:
    panels shrink so the PNG is at most this wide, or with ``wrap`` (one case: ``study run``) each row wraps onto
    as many rows as keep its panels at full size within that width. With ``path`` None: the PNG's bytes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm

    gain, errs = 2.0**exposure, part != "images"
    per_row = max(1, int((max_width_px / _DPI - 1.2 * errs) / 2.3)) if wrap and max_width_px else None
    tpl = _template(labels, part, outcome_panel, occlusion_panel, per_row)  # wrapped: panels stay legible
    ncol, nrow = max(len(r) for r in tpl), len(tpl) * len(cases)
    side = 2.3
    if max_width_px:
        side = max(0.6, min(side, (max_width_px / _DPI - 1.2 * errs) / ncol))
    kinds = {k for row in tpl for k, _ in row}
    legend_h = 0.75 if kinds & {"outcome", "hidden"} else 0.0  # inches under the grid for the legends
    height = side * nrow + 0.6 + legend_h + (0.4 * nrow if wrap else 0.0)  # wrapped rows: room for titles
    fig, axes = plt.subplots(nrow, ncol, figsize=(side * ncol + 1.2 * errs, height), squeeze=False)
    ocmap = ListedColormap(OUTCOME_COLORS).with_extremes(bad="white")
    onorm = BoundaryNorm(np.arange(-0.5, 4), ocmap.N)
    hcmap = ListedColormap(HIDDEN_COLORS).with_extremes(bad="white")
    norm = LogNorm(vmin=0.01, vmax=30)
    hm = occ_im = None
    binary = all(
        np.isin(c.occluded[np.isfinite(c.occluded)], (0.0, 1.0)).all()
        for c in cases
        if c.occluded is not None
    )
    fs = 8 if side >= 1.6 else 6.5
    titles = {
        "image": lambda lab: _wrap(lab),
        "mitsuba": lambda lab: "ray traced (Mitsuba)" if not _rough(cases[0]) else "lobe ray traced (truth)",
        "angle": lambda lab: f"angle error: {_wrap(lab)}",
        "outcome": lambda lab: f"outcome: {_wrap(lab)}",
        "hidden": lambda lab: "hidden from\nreference point",
    }
    for r, case in enumerate(cases):
        sy, sx = _crop_box(case.mask | (case.occluded > 0) if case.occluded is not None else case.mask)
        for t, row in enumerate(tpl):
            axr = axes[r * len(tpl) + t]
            for c, (kind, lab) in enumerate(row):
                ax = axr[c]
                if kind == "image":
                    ax.imshow(to_ldr(case.images[lab][sy, sx] * gain), interpolation="nearest")
                elif kind == "mitsuba":  # rough: the lobe's truth (Mitsuba's adds the lamp's highlight)
                    ref = case.truth if _rough(case) and case.truth is not None else case.mitsuba
                    ax.imshow(to_ldr(ref[sy, sx] * gain), interpolation="nearest")
                elif kind == "angle":
                    err = np.clip(case.angle_maps[lab][sy, sx], 0.01, None)
                    hm = ax.imshow(err, norm=norm, cmap="magma", interpolation="nearest")
                elif kind == "outcome":
                    ax.imshow(case.outcome_maps[lab][sy, sx], cmap=ocmap, norm=onorm, interpolation="nearest")
                elif kind == "hidden":
                    occ = np.where(case.mask | (case.occluded > 0), case.occluded, np.nan)[sy, sx]
                    occ_im = ax.imshow(
                        occ, vmin=0, vmax=1, cmap=hcmap if binary else "viridis", interpolation="nearest"
                    )
                if r == 0:
                    ax.set_title(titles[kind](lab), fontsize=fs)
            for ax in axr[len(row) :]:
                ax.axis("off")
            for ax in axr[: len(row)]:
                ax.set_xticks([])
                ax.set_yticks([])
        cx, cy, cz = case.scene.object.center
        axes[r * len(tpl), 0].set_ylabel(
            row_labels[r] if row_labels else f"({cx:g}, {cy:g}, {cz:g})", fontsize=fs
        )
    tfs = 10 if side >= 1.6 else 8  # the title wrapped to the figure's width (≈ 0.6 em a character)
    per_line = max(30, int(fig.get_figwidth() * 72 / (0.6 * tfs)))
    head = textwrap.fill(title + ("" if part == "all" else f" ({part})"), per_line)
    fig.suptitle(head, fontsize=tfs)
    top = 1 - ((head.count("\n") + 1) * 1.4 * tfs / 72 + 0.1) / height if wrap else 1  # wrapped: below it
    w = fig.get_figwidth()  # the colour bar and its label: 1.1 in on the right, any width
    fig.tight_layout(rect=(0, legend_h / height, 1 - (1.1 / w if errs else 0), top), h_pad=2.5 * wrap or None)
    last = tpl[-1]
    outs = [c for c, (k, _) in enumerate(last) if k == "outcome"]
    if outs:
        _outcome_legend(fig, axes[-1, outs[0]], axes[-1, outs[-1]])
    if occ_im is not None and last[-1][0] == "hidden":
        _hidden_legend(fig, axes[-1, len(last) - 1], binary, occ_im)
    if hm is not None:
        cax = fig.add_axes((1 - 0.95 / w, 0.15, 0.14 / w, 0.7))
        fig.colorbar(hm, cax=cax, label="angular error (deg)")
    if path is None:
        return png_bytes(fig, dpi=_DPI)
    atomic_savefig(fig, path, dpi=_DPI)
    return None


def image_grids(
    name: str,
    cases,
    labels,
    *,
    title: str,
    exposure: float | None = None,
    rule: str | None = None,
    wrap: bool = False,
    **kw,
) -> dict[str, bytes]:
    """The figure's grid PNGs: ``<name>.png`` whole where it is at most :data:`MAX_WIDTH_PX` wide, else the images
    in ``<name>.png`` and the error maps in ``<name>-errors.png``, each shrunk to fit a page. The images' exposure
    (EV; :func:`figure_exposure` of ``cases`` unless given) is stated at the end of the title with its ``rule``
    (default the figure's: the object's p99 → 0.8). ``wrap``: split grids wrap their rows instead of shrinking
    their panels (one case, :func:`image_grid`)."""
    if exposure is None:
        exposure = figure_exposure(cases)
    rule = rule or f"object's p99 → {WHITE:g}"
    kw.update(exposure=exposure, title=f"{title}, exposure {exposure:+.2f} EV ({rule})")
    ncol = (
        2 * len(labels)
        + 1
        + (len(labels) if kw.get("outcome_panel") else 0)
        + int(kw.get("occlusion_panel", 0))
    )
    if (2.3 * ncol + 1.2) * _DPI <= MAX_WIDTH_PX:
        return {f"{name}.png": image_grid(cases, labels, None, **kw)}
    return {
        f"{name}.png": image_grid(
            cases, labels, None, part="images", max_width_px=MAX_WIDTH_PX, wrap=wrap, **kw
        ),
        f"{name}-errors.png": image_grid(
            cases, labels, None, part="errors", max_width_px=MAX_WIDTH_PX, wrap=wrap, **kw
        ),
    }


def run_config_case(scene, methods, *, backend: str, cache, case_id: str, where: str):
    """:func:`start_case` for one row of a config (returns the function that finishes it); a refusal that names no
    file is blamed on ``where`` (the config and the row, e.g. ``configs/fig4.toml positions[2]``)."""
    with _blamed(where):
        finish = start_case(scene, methods, backend=backend, cache=cache, case_id=case_id)
    return lambda: _blamed(where)(finish)()


@contextmanager
def _blamed(where: str):
    try:
        yield
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
    quality: str = "preview",
    images: str = "all",
) -> list[dict]:
    """Run every position (or case) of a figure config with every method; write ``<out>/<name>.png`` and
    ``<out>/metrics.csv`` (one row per position or case × method). Returns the rows. ``quality``: a preset of
    :data:`study.harness.config.QUALITY` applied to every case (``paper``: 1024² renders). ``name`` is one plain
    name (:func:`study.harness.config.plain_name`): the figure's files stay inside ``out``. ``images``: which
    per-case images it writes (:mod:`study.outputs.case_images`: ``all`` EXRs and viewer, ``viewer``, ``none``)."""
    plain_name(name)
    image_choice(images)
    with pg.task(name, None) as job:  # stage lines and the ETA (study.progress)
        return _figure(config, out, name, backend, cache, progress, quality, job, images)


def _started(scenes, methods, backend: str, store, config, cfg):
    """((index, case id, seconds), finish) of each case, started up to its columns' threads (:func:`start_case`)."""
    for i, (case_id, sc) in enumerate(scenes):
        t0 = time.perf_counter()
        with pg.item(case_id):
            finish = run_config_case(sc, methods, backend=backend, cache=store, case_id=case_id,
                                     where=f"{config} {cfg.key_of(i)}")  # fmt: skip
        pg.advance(case_id)  # its own thread's part done: the counter and the ETA move on
        yield (i, case_id, time.perf_counter() - t0), finish


def _written(made: list, exrs: list, exposure: float) -> tuple[dict, list[dict]]:
    """The per-case files the writer made (viewer scripts and EXRs; EXRs alone beyond the picture) and the
    viewer's manifest entries, each starting at the figure's grid ``exposure``."""
    files, entries = {}, []
    for job_i in made:
        more, entry = job_i.result()
        entry["exposure_ev"] = round(float(exposure), 2)  # the figure's, known once every case is in
        files.update(more)
        entries.append(entry)
    for job_i in exrs:
        files.update(job_i.result())
    return files, entries


def _figure(config, out, name, backend, cache, progress, quality, job: pg.Task, images: str) -> list[dict]:
    cfg, scene, methods = load_figure_config(config, name=name)  # placement runs as a stage of its own
    preset = quality_overrides(quality)
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
    scenes = [
        (f"{name}-{suffix}", scene.with_updates({**over, **preset}, source=str(config)))
        for suffix, _, over in todo
    ]
    budget.check_backend(backend)
    store = Cache(cache)
    budget.check_cases(scenes, methods, source=str(config), tell=estimate.teller(methods, store, backend))
    job.total = len(scenes)
    every = [m.label for m in methods]
    titles = [None] * len(todo) if cfg.positions is not None else [lab for _, lab, _ in todo]
    shown = cfg.pictured()  # the picture: the first seed's rows it names (every case is measured)
    pictured = set(shown)
    stems = file_stems(cid for cid, _ in scenes)
    with locked(out), ThreadPoolExecutor(1) as writer:  # one command at a time here; files written at the end
        t_start = time.perf_counter()
        cases, rows, made, exrs = [], [], [], []

        for (i, case_id, own), case, waited in one_behind(
            _started(scenes, methods, backend, store, config, cfg)
        ):
            for r in case.rows:
                r["case_seconds"] = own + waited  # its own thread's time and the wait for its rows
            cases.append(case)
            rows += case.rows
            # the case's EXR and viewer images (the picture's cases: the other seeds and rows are measured, not
            # shown) are encoded beside the next case, not after the last one
            if images != "none" and i in pictured:
                made.append(writer.submit(viewer.case_files, name, stems[case_id], case, every,
                                          title=titles[i] or "", case_id=case_id, exr=images == "all"))  # fmt: skip
            elif images == "all":
                exrs.append(writer.submit(viewer.case_exr, stems[case_id], case, every))
            if progress:
                progress(i + 1, len(todo))
        mark = pg.Stages()
        mark("outputs")  # the grid PNGs, then the EXRs and viewer images the writer has made meanwhile
        exposure = figure_exposure([cases[i] for i in shown])
        meta = metadata(
            config,
            backend=backend,
            seed=scene.render.seed,
            methods=[m.label for m in methods],
            cases=len(todo),
            code=(run_config_case, *[type(m) for m in methods]),  # the table's code: cases and methods
            figure=name,
            quality=quality,
            exposure_ev=round(exposure, 4),  # of the grid's images (figure_exposure)
            exposure_rule=EXPOSURE_RULE,
            seconds=round(time.perf_counter() - t_start, 1),  # inputs, references, methods, metrics
        )
        pngs = image_grids(
            name,
            [cases[i] for i in shown],
            labels,
            title=f"{name}: {describe(scene)}, "
            f"reference point {list(scene.reference.point)}, cube {scene.render.cube_res}², "
            f"backend {backend}",
            occlusion_panel=cfg.occlusion_panel,
            outcome_panel=cfg.outcome_panel,
            row_labels=None if cfg.positions is not None else [todo[i][1] for i in shown],
            exposure=exposure,
        )
        made_files, entries = _written(made, exrs, exposure)
        files = {**table_files(rows, "metrics"), **pngs, **made_files}
        if entries:
            files[viewer.MANIFEST] = viewer.manifest_text(name, entries)
        mark.end()  # the outputs made (their writing aside): the figure's time split, summed over its cases
        meta["time_split"] = {**{k: round(sum(c.times.get(k, 0.0) for c in cases), 3) for k in pg.CASE_PARTS},
                              "outputs": round(mark.seconds.get("outputs", 0.0), 3)}  # fmt: skip
        files["metadata.json"] = json_text(meta, indent=2)
        # every byte is made: the output set lives only while they are written (study.io.write_set)
        write_set(out, files, [f"{name}.png", f"{name}-errors.png", "exr", "viewer"], lock=False)
    return rows
