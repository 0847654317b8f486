"""The ``grid`` kind (a config without ``kind``): image grids with error heatmaps, the metrics table and the per-case
images (:func:`study.outputs.figures.figure_positions`); in the report, the grid, its viewer and its table."""

from __future__ import annotations

from study.outputs.figures import figure_positions
from study.report.kinds import FigureKind, register_kind
from study.report.sections import figure_section

GRID = register_kind(
    FigureKind(name="grid", run=figure_positions, files=("metrics.csv",), section=figure_section, tables=True)
)
