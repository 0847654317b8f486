"""The declared columns of a results table, one row per column (in the manner of pyiqa's ``DEFAULT_CONFIGS``):
name, unit, direction, the printed tables that show it (and under which header), whether a 95 % interval comes with
it, and what it means.

Everything that lists columns reads this table: the column order of every CSV and Parquet (:mod:`study.tables`),
the columns :class:`study.api.Result` shows first and ``study run`` prints (view ``"run"``), the table ``study
figure`` prints (view ``"figure"``), the tolerances of ``study check`` (each must name a declared column). A column
a producer writes (:func:`study.measure.case.producer`) must be declared here, or with :func:`declare` by the
plug-in that adds it — then it reaches every output with no other file touched.

Directions: ``lower_is_better`` True for errors and costs, False for scores (PSNR, SSIM, correct fraction), None
for what describes the case (counts, positions, context). An ``interval`` column has ``<name>_lo`` / ``<name>_hi``
beside it (its 95 % interval; :mod:`study.measure.stats`), declared with it.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace

LOW, HIGH, NONE = True, False, None
#: the largest finite float: a domain ending here admits every finite number and not ±inf
FINITE = sys.float_info.max


@dataclass(frozen=True)
class TableColumn:
    name: str
    unit: str = (
        ""  # "fraction", "deg", "m", "linear RGB", "dB", "JND-free [0, 1]", "lookups", "s", "count", …
    )
    lower_is_better: bool | None = NONE
    header: str = ""  # short header in printed tables ("": the name)
    views: tuple[
        str, ...
    ] = ()  # printed tables that show it: "run" (study run, Result), "figure" (study figure)
    interval: bool = False  # <name>_lo / <name>_hi beside it
    note: str = ""
    #: its value hangs on the backend's float32 arithmetic: `study check` compares it with a stated floor
    #: (study.report.check.backend_floor), no ranking uses it (study.report.summary.ranking)
    backend_sensitive: bool = False
    #: the declared column whose calibrated ``_lo``/``_hi`` are this column's 95 % interval, where they are not its
    #: own (wrong_fraction → wrong_fraction_texel: the same rays, clustered by pixel); :func:`interval_bounds`
    interval_from: str = ""
    #: values a table may hold (closed, on the extended reals; NaN, an empty cell, always allowed): None takes the
    #: unit's (:func:`domain`); (-math.inf, math.inf) checks nothing
    domain: tuple[float, float] | None = None


C = TableColumn
F = "fraction"
#: every column of a results table, in the order tables write them (the rest of a row follows in the order first seen)
TABLE: list[TableColumn] = [
    # ------------------------------------------------------------------ the case
    C("case", note="the case's id (a figure's panel, a sweep's point)", views=("figure",)),
    C("method", note="the method's registered name (or a reference: oracle_map, truth_at_hit)"),
    C("label", note="the method with its parameters, e.g. localized(iterations=10)", views=("run", "figure")),
    C("family", note="the label without the knob"),
    C("knob", note="the parameter that moves the method along its cost/accuracy curve ('' without one)"),
    C("knob_value", note="the knob's value (NaN without one)"),
    C("cube_res", "texels", note="cube-map resolution per face"),
    C("object_x", "m", note="the object's centre"),
    C("object_y", "m"),
    C("object_z", "m"),
    C("object_alpha", note="the object's GGX roughness (rough objects only)"),
    C("displacement", F, note="|object − reference point| over the scene's diagonal"),
    # ------------------------------------------------------------------ geometry of the shown point
    C(
        "angle_median_deg",
        "deg",
        LOW,
        "angle med. °",
        ("run", "figure"),
        True,
        "angle at the shading point between the shown and the exact hit",
    ),
    C("angle_p95_deg", "deg", LOW, views=("figure",), interval=True),
    C("angle_max_deg", "deg", LOW),
    C("dist_median", "m", LOW, note="|shown − exact hit|, median over rays"),
    # ------------------------------------------------------------------ outcome classes (study.measure.outcomes)
    C(
        "correct_fraction",
        F,
        HIGH,
        note="rays whose shown point lies within ε = max(1 cm, one texel) of the hit",
    ),
    C(
        "wrong_fraction",
        F,
        LOW,
        "wrong",
        ("run",),
        note="1 − correct (texel-relative ε; = wrong_fraction_texel)",
        interval_from="wrong_fraction_texel",
    ),
    C("wrong_depth_fraction", F, LOW, note="wrong, on the exact hit's own surface but at another depth"),
    C("wrong_surface_fraction", F, LOW, note="wrong, on another surface"),
    C("no_hit_fraction", F, LOW, note="the method answered no point"),
    C("wrong_fraction_visible", F, LOW, "wrong vis.", ("run",), True, "wrong among rays whose hit o sees"),
    C(
        "wrong_fraction_hidden",
        F,
        LOW,
        "wrong hid.",
        ("run",),
        True,
        "wrong among rays whose hit o cannot see",
    ),
    C("hidden_fraction", F, note="rays whose exact hit is hidden from the reference point"),
    C("dist_p50", "m", LOW),
    C("dist_p95", "m", LOW, "dist p95 m", ("run",), True),
    C("dist_p99", "m", LOW),
    C("depth_error_p95", "m", LOW, note="depth error along the ray, p95"),
    C("angle_p95_visible_deg", "deg", LOW),
    C("angle_p95_hidden_deg", "deg", LOW),
    # ------------------------------------------------------------------ image errors (study.measure.metrics)
    C(
        "rmse_oracle",
        "linear RGB",
        LOW,
        views=("figure",),
        note="RMSE against the oracle_map, on held pixels",
    ),
    C("psnr_oracle", "dB", HIGH),
    C("ssim_oracle", "", HIGH),
    C("flip_oracle", "", LOW),
    C(
        "rmse_mitsuba",
        "linear RGB",
        LOW,
        "RMSE Mitsuba",
        ("figure",),
        note="RMSE against Mitsuba's render with the object: not a measure of the method alone, so not shown "
        "by study run. That render carries light no method models (the point light's highlight on glossy and "
        "mirror objects, the object's shadow and own reflections) and both renders' noise, so the exact traced "
        "row can score worse than a smooth stand-in; truth_at_hit's row gives the part no method can remove "
        "(study/measure/lighting.py says so where it is large). Rank on rmse_truth or relmse_truth_exposed",
    ),
    C("psnr_mitsuba", "dB", HIGH),
    C("ssim_mitsuba", "", HIGH),
    C("flip_mitsuba", "", LOW),
    C("occluded_fraction", F, views=("figure",), note="rays whose exact hit is hidden from o (the case's)"),
    # ------------------------------------------------------------------ the trace and its cost
    C("valid_fraction", F, HIGH, note="rays the method marked valid"),
    C("ratio_residual_median", "", LOW, note="|distance ratio − 1| at the search's end, median"),
    C("lookups_per_ray", "lookups", LOW, "lookups", ("run",), note="mean cube-map lookups a ray spent"),
    C("lookups_bound", "lookups", LOW, note="the method's bound (what budgets and floors count)"),
    C("rays", "count", note="the object's secondary rays"),
    C("backend", note="numpy, llvm or cuda"),
    C("seconds", "s", LOW, note="wall time of the trace (measured, never in a baseline)"),
    # ------------------------------------------------------------------ counts and intervals (study.measure.stats)
    C("n_rays", "count"),
    C(
        "rays_deff",
        note="design effect of wrong_fraction: its variance with rays clustered by pixel over the "
        "binomial variance of independent rays; the fractions' intervals use n_rays / rays_deff rays",
    ),
    C("n_hidden", "count"),
    C("n_wrong", "count"),
    C("wrong_fraction_texel", F, LOW, interval=True, note="wrong with ε = max(1 cm, one texel at the hit)"),
    C("wrong_fraction_1mm", F, LOW, note="wrong with ε = 1 mm (the same at every resolution)"),
    C("wrong_fraction_3mm", F, LOW),
    C("wrong_fraction_1cm", F, LOW, interval=True),
    C("wrong_fraction_3cm", F, LOW, interval=True),
    C("wrong_fraction_10cm", F, LOW, interval=True),
    C("wrong_fraction_30cm", F, LOW),
    C(
        "wrong_fraction_0p5deg",
        F,
        LOW,
        interval=True,
        note="|shown − exact| subtends > 0.5° from the shading point",
    ),
    C("angle_dropped", F, note="rays without a finite angle (no hit), left out of angle_*"),
    C("dist_dropped", F, note="rays without a finite distance, left out of dist_*"),
    C(
        "angle_p95_all_deg",
        "deg",
        LOW,
        note="angle p95 counting rays without a hit as infinite",
        domain=(0.0, math.inf),
    ),
    C("offscreen_fraction", F, note="rays whose exact hit lies outside the camera's frame"),
    C("wrong_fraction_offscreen", F, LOW, note="wrong among those (what screen-space methods cannot show)"),
    C("flip_oracle_p95", "", LOW),
    C("rmse_truth", "linear RGB", LOW, "RMSE truth", ("run",), True, "RMSE against truth_at_hit"),
    C("psnr_truth", "dB", HIGH),
    C("ssim_truth", "", HIGH),
    C("flip_truth", "", LOW, "FLIP truth", ("run", "figure"), True, "LDR-FLIP against truth_at_hit, mean"),
    C("flip_truth_p95", "", LOW),
    C("flip_mitsuba_p95", "", LOW),
    C(
        "rmse_truth_debiased",
        "linear RGB",
        LOW,
        interval=True,
        note="√max(0, RMSE² − σ²): the truth's noise out",
    ),
    C(
        "relmse_truth",
        "",
        LOW,
        interval=True,
        note="relative MSE, (img − ref)² / (ref² + ε), ε = 0.01 absolute",
    ),
    C(
        "relmse_truth_exposed",
        "",
        LOW,
        "relMSE exp.",
        ("run",),
        True,
        "relMSE after exposure: images × 2^truth_exposure_ev, then (img − ref)² / (ref² + ε), ε = 0.01 (√ε about "
        "half of middle grey: darker pixels count about absolutely, so their noise cannot dominate); the same for a "
        "scene × k, so it ranks methods alike in dark and bright scenes (study/measure/exposure.py); the summary "
        "ranks image error on it",
    ),
    C(
        "truth_noise_relmse",
        "",
        note="the truth's own noise in relmse_truth_exposed's unit: its part of every row's",
    ),
    C(
        "truth_exposure_ev",
        "EV",
        note="exposure of the truth over the object's pixels (median → 0.18, p95 ≤ 1)",
    ),
    C(
        "firefly_fraction",
        F,
        LOW,
        note="pixels of Mitsuba's render whose displayed luminance (its exposure, clipped at 1) differs between "
        "its two seeds by > 0.25: over 0.02 the picture is labelled FIREFLIES",
    ),
    C(
        "own_light_share",
        F,
        note="the file's own lights' power over study's point light's (luminance, W); under 0.05 they are weak and "
        "study's point light is added unless light.enabled is given (study/scene/lights.py); NaN: not judged",
        domain=(0.0, FINITE),
    ),
    # worth looking at (study/measure/worth.py): past its limit, `study run` names the cause and the key to change
    C(
        "black_share",
        F,
        LOW,
        note="Mitsuba's picture shown black after its exposure (at most 8 EV of boost); > 0.5",
    ),
    C("clipped_share", F, LOW, note="Mitsuba's picture clipped white after its exposure; > 0.1"),
    C("object_share", F, note="the frame's pixels fully on the object; < 0.02"),
    C("mirrored_void", F, LOW, note="the object's rays that leave the scene (no sky given: black); > 0.5"),
    C(
        "reference_seen",
        F,
        note="the object's bounding sphere as seen unblocked from the reference point; < 0.5",
    ),
    C(
        "own_shadow",
        F,
        note="the object's rays whose exact hit lies in the object's own shadow from the point light: Mitsuba's "
        "render is darker there than truth_at_hit (taken without the object); NaN: no point light",
    ),
    C("truth_noise_rmse", "linear RGB", note="the truth's own noise σ"),
    C(
        "truth_noise_flag",
        note="1 where the truth's noise σ exceeds a third of the debiased error it measures (Whittle et al. 2017)",
    ),
    C(
        "rmse_mitsuba_debiased",
        "linear RGB",
        LOW,
        note="rmse_mitsuba less Mitsuba's noise (rmse_mitsuba's caveat holds)",
    ),
    C("mitsuba_noise_rmse", "linear RGB", note="Mitsuba's own noise σ over the same pixels"),
    C("mitsuba_noise_flag", note="1 where Mitsuba's noise σ exceeds a third of rmse_mitsuba_debiased"),
    C(
        "mitsuba_noise_frame",
        "linear RGB",
        note="Mitsuba's noise over the whole frame (1.4826 × median |half the seeds' difference|): tight over "
        "seeds, so `study check` sees a render at half its samples",
    ),
    C("n_pixels", "count"),
    C("n_blocks", "count", note="pixel blocks resampled for the pixel intervals (tables before corr_px)"),
    C(
        "corr_px",
        "px",
        note="correlation length of the squared error over the pixels (autocorrelation 1/e); the "
        "pixel intervals sum its covariance over a lag window that follows it",
    ),
    C("rmse_truth_trim", "linear RGB", LOW, note="RMSE without the worst 0.1 % of pixels"),
    C("rmse_truth_debiased_trim", "linear RGB", LOW),
    C("sqerr_top_share_truth", F, note="share of the squared error the worst 0.1 % of pixels carry"),
    # ------------------------------------------------------------------ the error split (study.measure.split)
    C("held_pixels", "count", note="object pixels whose every hit the views hold"),
    C("unheld_pixels", "count"),
    C("held_fraction", F, note="rays whose exact hit o's views hold (reference rows)"),
    C("dec_total", "MSE", LOW, interval=True, note="the split's total: MSE against the truth"),
    C("dec_search", "MSE", LOW, interval=True, note="the search's share (method vs oracle on held pixels)"),
    C("dec_visibility", "MSE", LOW, interval=True),
    C("dec_representation", "MSE", LOW, interval=True),
    C("dec_noise", "MSE", LOW, interval=True),
    C("dec_cross", "MSE", interval=True),
    C("dec_residual", "MSE", interval=True),
    C("dec_sums", F, note="Σ terms / total", domain=(-math.inf, math.inf)),
    C(
        "dec_representation_direct",
        "MSE",
        LOW,
        interval=True,
        note="the map's share measured against the truth: oracle vs truth_at_hit on held pixels, noise removed",
    ),
    C(
        "dec_sums_direct",
        F,
        note="search + visibility + representation_direct + noise meet the total",
        domain=(-math.inf, math.inf),
    ),
    C("rmse_truth_held", "linear RGB", LOW, interval=True),
    C("rmse_truth_unheld", "linear RGB", LOW, interval=True),
    C(
        "radiance_bias_truth",
        "ratio − 1",
        note="signed: Σ radiance / Σ truth_at_hit's − 1 over the held object pixels (study.measure.bias); a method "
        "3 % too bright reads +0.03 whatever its search",
    ),
    C(
        "surface_mismatch",
        note="1: the method does not model the object's surface (scored with --allow-mismatch)",
    ),
]
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
#: the leading columns: every results table writes these first, in this order; the rest of a row follows in the order
#: it first appears (so tables written before a column was declared keep their layout)
LEAD = [c.name for c in TABLE[: [c.name for c in TABLE].index("seconds") + 1]]
#: the views a printed table may name, in the order of :data:`TABLE` unless :data:`ORDER` says otherwise
ORDER = {
    "run": ["label", "wrong_fraction", "wrong_fraction_visible", "wrong_fraction_hidden", "dist_p95",
            "angle_median_deg", "rmse_truth", "relmse_truth_exposed", "flip_truth", "lookups_per_ray"],
    "figure": ["case", "label", "angle_median_deg", "angle_p95_deg", "rmse_oracle", "rmse_mitsuba", "flip_truth",
               "occluded_fraction"],
}  # fmt: skip

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


def headers() -> dict[str, str]:
    """Short headers of printed tables: name → header, for the columns that have one."""
    return {c.name: c.header for c in TABLE if c.header}


for _c in TABLE:  # the table's own columns, indexed by name
    _index(_c)
#: the built-in columns (each interval's ``_lo``/``_hi`` with it): a plug-in's producer may write none of them
BUILTIN = frozenset(column_names())
