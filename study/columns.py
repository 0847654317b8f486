"""The declared columns of a results table, one row per column (in the manner of pyiqa's ``DEFAULT_CONFIGS``;
the rows are in :mod:`study.column_rows`): name, unit, direction, the printed tables, report sections and plots that
show it (its views, and under which header and axis label), whether a 95 % interval comes with it, and what it means.

Everything that lists columns reads this table: the column order of every CSV and Parquet (:mod:`study.tables`),
the columns :class:`study.api.Result` shows first and ``study run`` prints (view ``"run"``), the table ``study
figure`` prints (view ``"figure"``), the report's summary, error split and comparison (views ``"summary"``,
``"decomposition"``, ``"comparison"``), the metrics a plot draws with their axis label and log floor (views
``"plots"``, ``"pareto"``, ``"convergence"``: :func:`in_view`, :func:`axis`), the columns of ``curves.csv`` (view
``"curves"``), the tolerances of ``study check`` (each must name a declared column). A column a producer writes
(:func:`study.measure.producers.producer`) must be declared here, or with :func:`declare` by the plug-in that adds
it — then it reaches every output with no other file touched; the producer names the columns it writes, and a name
two producers write is an error when the second registers (a built-in column, :data:`BUILTIN`, included). Study's
other tables (the bench's, its floors and projection, the caustics', the report's power table) are declared the same
way (:mod:`study.column_tables`, :func:`table_columns`).

Directions: ``lower_is_better`` True for errors and costs, False for scores (PSNR, SSIM, correct fraction), None
for what describes the case (counts, positions, context). An ``interval`` column has ``<name>_lo`` / ``<name>_hi``
beside it (its 95 % interval; :mod:`study.stats`), declared with it.
"""

from __future__ import annotations

import math
from dataclasses import replace

from study.column_rows import (  # noqa: F401 - the table's API
    FINITE,
    HIGH,
    LOW,
    NONE,
    TABLE,
    F,
    TableColumn,
)
from study.column_tables import TABLES

#: The columns whose values hang on the backend's float32 arithmetic (CUDA against numpy/LLVM differ by up
#: to 12 % in them with the same captures): percentiles of near-zero angles and distances, the p95s that non-converged
#: rays set, march step counts. Marked here (``backend_sensitive``) rather than in each row above, so that other
#: fields of those rows change apart; a plug-in's column passes ``backend_sensitive=True`` to :func:`declare`.
BACKEND_SENSITIVE = (
    "angle_median_deg", "angle_p95_deg", "angle_max_deg", "angle_p95_visible_deg", "angle_p95_hidden_deg",
    "angle_p95_all_deg", "dist_median", "dist_p50", "dist_p95", "dist_p99", "depth_error_p95",
    "ratio_residual_median", "lookups_per_ray",
)  # fmt: skip
TABLE[:] = [replace(c, backend_sensitive=True) if c.name in BACKEND_SENSITIVE else c for c in TABLE]
#: the views a printed table may name, in the order of :data:`TABLE` unless :data:`ORDER` says otherwise
ORDER = {
    "run": ["label", "wrong_fraction", "wrong_fraction_visible", "wrong_fraction_hidden", "dist_p95",
            "angle_median_deg", "rmse_truth", "relmse_truth_exposed", "flip_truth", "lookups_per_ray"],
    "figure": ["case", "label", "angle_median_deg", "angle_p95_deg", "rmse_oracle", "rmse_mitsuba", "flip_truth",
               "occluded_fraction"],
    # the report (study.report.report): the summary's medians (outcome classes first: the angle alone is blind to a
    # wrong depth on the same ray), the error split's (study.measure.split: MSE parts that add up to dec_total),
    # the comparison's (also fixed tolerances, one meaning at every cube resolution, and robust image errors)
    "summary": ["wrong_fraction", "wrong_fraction_visible", "wrong_fraction_hidden", "dist_p95", "dist_dropped",
                "angle_dropped", "wrong_fraction_offscreen", "angle_median_deg", "angle_p95_deg", "rmse_oracle",
                "rmse_truth_debiased", "rmse_mitsuba_debiased", "flip_truth", "occluded_fraction", "lookups_per_ray"],
    "decomposition": ["dec_total", "dec_search", "dec_visibility", "dec_representation", "dec_noise", "dec_cross",
                      "dec_residual", "dec_sums", "dec_representation_direct", "dec_sums_direct", "held_pixels",
                      "unheld_pixels", "rmse_truth_held", "rmse_truth_unheld", "rmse_truth", "rmse_truth_debiased",
                      "truth_noise_rmse", "truth_noise_flag", "rmse_mitsuba", "rmse_mitsuba_debiased",
                      "mitsuba_noise_rmse", "mitsuba_noise_flag"],
    "comparison": ["wrong_fraction", "wrong_fraction_visible", "wrong_fraction_hidden", "dist_p95", "dist_dropped",
                   "angle_dropped", "wrong_fraction_1cm", "wrong_fraction_10cm", "wrong_fraction_0p5deg",
                   "relmse_truth", "relmse_truth_exposed", "rmse_truth_debiased_trim", "sqerr_top_share_truth",
                   "wrong_fraction_offscreen", "angle_p95_deg", "rmse_oracle", "rmse_truth_debiased",
                   "rmse_mitsuba_debiased", "flip_truth", "valid_fraction", "lookups_per_ray"],
    # the plots that draw one metric per figure (study.outputs.plots), the pareto page's error axis
    # (study.report.pareto), the panels of the convergence figure (study.outputs.convergence): each with its axis
    "plots": ["wrong_fraction", "angle_median_deg", "angle_p95_deg"],
    "pareto": ["wrong_fraction", "rmse_truth_debiased", "wrong_fraction_1cm"],
    # the convergence figure's curves.csv beside each ladder's columns (study.outputs.convergence)
    "curves": ["label", "lookups_per_ray", "n_rays", "wrong_fraction_texel", "wrong_fraction_texel_lo",
               "wrong_fraction_texel_hi", "wrong_fraction_1cm", "wrong_fraction_1cm_lo", "wrong_fraction_1cm_hi",
               "wrong_fraction_3cm", "wrong_fraction_3cm_lo", "wrong_fraction_3cm_hi", "wrong_fraction_10cm",
               "wrong_fraction_10cm_lo", "wrong_fraction_10cm_hi", "wrong_fraction_visible",
               "wrong_fraction_visible_lo", "wrong_fraction_visible_hi", "wrong_fraction_hidden", "angle_p95_deg",
               "angle_p95_all_deg", "rmse_truth", "hidden_fraction"],
    "convergence": ["wrong_fraction_texel", "wrong_fraction_visible", "wrong_fraction_1cm", "wrong_fraction_3cm",
                    "wrong_fraction_10cm", "angle_p95_deg", "rmse_truth"],
}  # fmt: skip
#: a row is in each view that :data:`ORDER` lists it in (the view's order is ORDER's): marked here once
TABLE[:] = [
    replace(c, views=c.views + tuple(v for v, names in ORDER.items() if c.name in names and v not in c.views))
    for c in TABLE
]
#: the leading columns: every results table writes these first, in this order; the rest of a row follows in the order
#: it first appears (so tables written before a column was declared keep their layout)
LEAD = [c.name for c in TABLE[: [c.name for c in TABLE].index("seconds") + 1]]

_BY_NAME: dict[str, TableColumn] = {}


def _index(c: TableColumn) -> None:
    if c.name in _BY_NAME:
        raise ValueError(f"column {c.name!r} is declared twice")
    _BY_NAME[c.name] = c
    for v in c.views:
        if c.name not in ORDER.setdefault(v, []):
            ORDER[v].append(c.name)


def declare(*cols: TableColumn) -> None:
    """Add columns to the table (a plug-in's): a name declared twice is an error."""
    for c in cols:
        _index(c)
        TABLE.append(c)


def declared(name: str) -> TableColumn | None:
    """The declared column ``name`` (an interval's ``_lo``/``_hi`` resolves to its column), or None."""
    if name in _BY_NAME:
        return _BY_NAME[name]
    for end in ("_lo", "_hi"):
        base = _BY_NAME.get(name.removesuffix(end)) if name.endswith(end) else None
        if base is not None and base.interval:
            return base
    return None


def interval_bounds(name: str) -> tuple[str, str] | None:
    """The ``_lo``/``_hi`` columns that hold the calibrated 95 % interval of column ``name`` (its own where it is
    declared with ``interval``, else those of the column its ``interval_from`` names); None where none is declared
    (then no interval is invented for it: the report calls a comparison on it undecided)."""
    c = _BY_NAME.get(name)
    if c is None:
        return None
    src = _BY_NAME.get(c.interval_from) if c.interval_from else c
    return (f"{src.name}_lo", f"{src.name}_hi") if src is not None and src.interval else None


def column_names() -> list[str]:
    """Every declared name in table order, each interval column followed by its _lo and _hi."""
    return [n for c in TABLE for n in ((c.name, f"{c.name}_lo", f"{c.name}_hi") if c.interval else (c.name,))]


#: the values a column of a unit may hold where its row names no domain: fractions in [0, 1], counts, costs, times
#: and image errors finite and ≥ 0, angles in [0°, 180°]; errors in metres ≥ 0 (positions are not checked)
UNIT_DOMAINS = {
    F: (0.0, 1.0),
    "count": (0.0, FINITE),
    "lookups": (0.0, FINITE),
    "texels": (0.0, FINITE),
    "px": (0.0, FINITE),
    "s": (0.0, FINITE),
    "linear RGB": (0.0, FINITE),
    "deg": (0.0, 180.0),
}


def domain(name: str) -> tuple[float, float] | None:
    """The values the declared column ``name`` may hold (its row's ``domain``, else its unit's,
    :data:`UNIT_DOMAINS`; an error in metres ≥ 0), None where nothing is checked (undeclared, or a unit without
    one). An interval's ``_lo``/``_hi`` takes its column's.

    Parameters
    ----------
    name : str
        A column of a results table.

    Returns
    -------
    tuple of float or None
        (lowest, highest), closed on the extended reals.
    """
    c = declared(name)
    if c is None:
        return None
    if c.domain is not None:
        return None if c.domain == (-math.inf, math.inf) else c.domain
    if c.unit == "m" and c.lower_is_better:
        return (0.0, FINITE)
    return UNIT_DOMAINS.get(c.unit)


def view(name: str) -> list[str]:
    """The columns a printed table shows, in its order."""
    return list(ORDER.get(name, []))


def table_columns(name: str, view: str = "") -> list[str]:
    """The columns of study's other table ``name`` (:data:`study.column_tables.TABLES`: ``bench``, ``bench_floors``,
    ``projection``, ``caustics``, ``power``) in the order its CSV writes them, or those of its ``view`` (in the
    view's declared order, else the rows' order)."""
    if name not in TABLES:
        raise KeyError(f"no declared table {name!r}; declared: {', '.join(TABLES)}")
    rows, orders = TABLES[name]
    if not view:
        return [c.name for c in rows]
    return list(orders.get(view) or [c.name for c in rows if view in c.views])


def in_view(name: str) -> list[TableColumn]:
    """The declared rows of view ``name`` (a printed table, a report section, a plot's metrics), in its order."""
    return [_BY_NAME[n] for n in ORDER.get(name, []) if n in _BY_NAME]


def axis(name: str) -> str:
    """The axis label of column ``name`` (its row's ``axis``; the name where it has none or is not declared)."""
    c = declared(name)
    return c.axis if c is not None and c.axis else name


def headers() -> dict[str, str]:
    """Short headers of printed tables: name → header, for the columns that have one."""
    return {c.name: c.header for c in TABLE if c.header}


for _c in TABLE:  # the table's own columns, indexed by name
    _index(_c)
for _t, (_rows, _orders) in TABLES.items():  # each other table's views name its rows, once each
    _names = [c.name for c in _rows]
    if len(set(_names)) < len(_names) or any(set(o) - set(_names) for o in _orders.values()):
        raise ValueError(f"table {_t!r}: a column declared twice, or a view naming an undeclared one")
if _missing := {v: bad for v, ns in ORDER.items() if (bad := [n for n in ns if declared(n) is None])}:
    raise ValueError(f"views name undeclared columns: {_missing}")
#: the built-in columns (each interval's ``_lo``/``_hi`` with it): a plug-in's producer may write none of them
BUILTIN = frozenset(column_names())
