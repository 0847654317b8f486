"""The ``glossy`` kind (``configs/fig_glossy.toml``): a grid figure, then its error split written beside it —
``split.csv`` and ``glossy.md`` (:func:`study.outputs.glossy.write_split`); in the report, the grid's section and
the split's table."""

from __future__ import annotations

from pathlib import Path

from study.outputs import glossy
from study.outputs.figures import figure_positions
from study.outputs.markup import link
from study.report.kinds import FigureKind, register_kind
from study.report.sections import figure_section
from study.tables import read_csv


def glossy_figure(config, out, **kw) -> list[dict]:
    """The grid figure of ``config`` into ``out``, then its error split (``split.csv``, ``glossy.md``)."""
    rows = figure_positions(config, out, **kw)
    glossy.write_split(Path(out))
    return rows


def split_section(reports: Path, d: Path, table: list[dict], cols: list[str]) -> list[tuple]:
    """The grid's section, then the error split written beside it (a heading, the source and the table; nothing
    for an empty ``split.csv``)."""
    rows = read_csv(d / "split.csv")
    out = figure_section(reports, d, table, cols)
    if not rows:  # no section of an empty table
        return out
    return out + [
        ("h", 3, "Error split"),
        (
            "p",
            f"Prefiltering, localization, visibility and noise with 95 % intervals over blocks of pixels "
            f"({link(f'{d.name}/split.csv', f'{d.name}/split.csv')}; study/outputs/glossy.py).",
        ),
        ("table", rows, list(rows[0])),
    ]


GLOSSY = register_kind(
    FigureKind(
        name="glossy",
        run=glossy_figure,
        files=("metrics.csv", "split.csv"),
        section=split_section,
        tables=True,
    )
)
