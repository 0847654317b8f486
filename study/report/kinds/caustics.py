"""The ``caustics`` kind (``configs/fig8.toml``): Figure 8, a glass sphere's caustics from a caustic map
(:func:`study.caustics.figure.fig8`; ``study caustics-sweep`` adds the sweep over resolutions); in the report, the
light-map error against exact photon tracing (a), the image error against Mitsuba's ptracer (b), the time per map."""

from __future__ import annotations

from pathlib import Path

from study import columns
from study.caustics.figure import fig8
from study.report.check import read_table
from study.report.kinds import AFTER_SWEEPS, FigureKind, register_kind
from study.report.sections import shown

CAUSTIC_COLS = columns.table_columns("caustics", "report")  # the report's table (study/column_tables.py)
#: The columns ``study figure`` prints per row.
PRINTED = tuple(columns.table_columns("caustics", "printed"))


def caustics_figure(
    config, out, *, name=None, backend="numpy", cache=".cache", quality="preview", sweep=False
):
    """Figure 8 of ``config`` into ``out`` (the caustic map is made at the config's own resolution whatever the
    ``quality``); with ``sweep`` also the sweep over the config's resolutions."""
    return fig8(config, out, backend=backend, cache=cache, sweep=sweep)


def caustics_lines(rows: list[dict]) -> list[str]:
    """One line per row: its :data:`PRINTED` columns as ``key=value``."""
    return [
        ", ".join(
            f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items() if k in PRINTED
        )
        for r in rows
    ]


def caustics_section(reports: Path, d: Path, table: list[dict], cols: list[str]) -> list[tuple]:
    """Figure 8's images and, where ``study caustics-sweep`` wrote it (``sweep/results.csv``), the sweep's table."""
    rel = d.relative_to(reports).as_posix()
    pngs = shown(d.glob("*.png"))
    if not (d / "sweep" / "results.csv").is_file():
        return (
            [("h", 2, f"{rel}: caustics"), *[("img", f"{rel}/{p.name}", rel) for p in pngs]] if pngs else []
        )
    rows = read_table(d / "sweep" / "results.csv", required=("label",), numeric=["caustic_res"])
    out = [
        ("h", 2, f"{rel}: caustics"),
        (
            "p",
            "Glass sphere (n = 1.3) focusing the point light; caustic map from the light, photon hits localized "
            "in the distance impostor, splatted into light maps (study/caustics/photons.py, "
            "study/caustics/lightmap.py). "
            "lm_* = light-map error against exact photon tracing (a), W/m²; img_* = caustic-only image against "
            "Mitsuba ptracer (b); mitsuba_noise_rmse = Mitsuba's own noise (two seeds). "
            f"Table: [{rel}/sweep/results.csv]({rel}/sweep/results.csv).",
        ),
    ]
    out += [("img", f"{rel}/{p.name}", rel) for p in pngs]
    return out + [("table", rows, CAUSTIC_COLS)]


CAUSTICS = register_kind(
    FigureKind(
        name="caustics",
        run=caustics_figure,
        files=("fig8.csv",),
        section=caustics_section,
        place=AFTER_SWEEPS,
        rank=10,
        lines=caustics_lines,
    )
)
