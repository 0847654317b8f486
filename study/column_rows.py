"""The rows of the declared column table (:mod:`study.columns`): one :class:`TableColumn` per column of a results
table — name, unit, direction, views, interval, axis label, log floor, what it means — every field by keyword.
"""

from __future__ import annotations

import math
import sys
from dataclasses import KW_ONLY, dataclass

LOW, HIGH, NONE = True, False, None
#: the largest finite float: a domain ending here admits every finite number and not ±inf
FINITE = sys.float_info.max


@dataclass(frozen=True)
class TableColumn:
    name: str
    #: "fraction", "deg", "m", "linear RGB", "dB", "JND-free [0, 1]", "lookups", "s", "count", …
    unit: str = ""
    lower_is_better: bool | None = NONE
    header: str = ""  # short header in printed tables ("": the name)
    #: the printed tables, report sections and plots that show it: "run" (study run, Result), "figure" (study
    #: figure), "summary", "decomposition", "comparison" (the report), "plots", "pareto", "convergence"
    #: (:data:`study.columns.ORDER` gives each view's order)
    views: tuple[str, ...] = ()
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
    _: KW_ONLY
    #: the axis label of every plot that draws it (one spelling; the pareto page adds "(median over cases)")
    axis: str = ""
    #: on a log axis, values at or below it are drawn at it (marked, not hidden); None: no floor of its own
    log_floor: float | None = None


def C(name: str, **fields) -> TableColumn:
    """A row of :data:`TABLE`: its name, then every field by keyword."""
    return TableColumn(name, **fields)


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
    C("cube_res", unit="texels", note="cube-map resolution per face"),
    C("object_x", unit="m", note="the object's centre"),
    C("object_y", unit="m"),
    C("object_z", unit="m"),
    C("object_alpha", note="the object's GGX roughness (rough objects only)"),
    C("displacement", unit=F, note="|object − reference point| over the scene's diagonal"),
    # ------------------------------------------------------------------ geometry of the shown point
    C(
        "angle_median_deg",
        unit="deg",
        lower_is_better=LOW,
        header="angle med. °",
        views=("run", "figure"),
        interval=True,
        note="angle at the shading point between the shown and the exact hit",
        axis="median angular error (deg)",
        log_floor=1e-6,
    ),
    C(
        "angle_p95_deg",
        unit="deg",
        lower_is_better=LOW,
        views=("figure",),
        interval=True,
        axis="p95 angular error (deg)",
        log_floor=1e-6,
    ),
    C("angle_max_deg", unit="deg", lower_is_better=LOW),
    C("dist_median", unit="m", lower_is_better=LOW, note="|shown − exact hit|, median over rays"),
    # ------------------------------------------------------------------ outcome classes (study.measure.outcomes)
    C(
        "correct_fraction",
        unit=F,
        lower_is_better=HIGH,
        note="rays whose shown point lies within ε = max(1 cm, one texel) of the hit",
    ),
    C(
        "wrong_fraction",
        unit=F,
        lower_is_better=LOW,
        header="wrong",
        views=("run",),
        note="1 − correct (texel-relative ε; = wrong_fraction_texel)",
        interval_from="wrong_fraction_texel",
        axis="fraction of wrong rays",
        log_floor=1e-4,
    ),
    C(
        "wrong_depth_fraction",
        unit=F,
        lower_is_better=LOW,
        note="wrong, on the exact hit's own surface but at another depth",
    ),
    C("wrong_surface_fraction", unit=F, lower_is_better=LOW, note="wrong, on another surface"),
    C("no_hit_fraction", unit=F, lower_is_better=LOW, note="the method answered no point"),
    C(
        "wrong_fraction_visible",
        unit=F,
        lower_is_better=LOW,
        header="wrong vis.",
        views=("run",),
        interval=True,
        note="wrong among rays whose hit o sees",
        axis="wrong (> 1 texel), hits o sees",
    ),
    C(
        "wrong_fraction_hidden",
        unit=F,
        lower_is_better=LOW,
        header="wrong hid.",
        views=("run",),
        interval=True,
        note="wrong among rays whose hit o cannot see",
    ),
    C("hidden_fraction", unit=F, note="rays whose exact hit is hidden from the reference point"),
    C("dist_p50", unit="m", lower_is_better=LOW),
    C("dist_p95", unit="m", lower_is_better=LOW, header="dist p95 m", views=("run",), interval=True),
    C("dist_p99", unit="m", lower_is_better=LOW),
    C("depth_error_p95", unit="m", lower_is_better=LOW, note="depth error along the ray, p95"),
    C("angle_p95_visible_deg", unit="deg", lower_is_better=LOW),
    C("angle_p95_hidden_deg", unit="deg", lower_is_better=LOW),
    # ------------------------------------------------------------------ image errors (study.measure.metrics)
    C(
        "rmse_oracle",
        unit="linear RGB",
        lower_is_better=LOW,
        views=("figure",),
        note="RMSE against the oracle_map, on held pixels; NaN on the exact rows (traced, traced_glossy), which "
        "read no cube map, as every *_oracle and dec_* column (Method.reads_views)",
    ),
    C("psnr_oracle", unit="dB", lower_is_better=HIGH),
    C("ssim_oracle", unit="", lower_is_better=HIGH),
    C("flip_oracle", unit="", lower_is_better=LOW),
    C(
        "rmse_mitsuba",
        unit="linear RGB",
        lower_is_better=LOW,
        header="RMSE Mitsuba",
        views=("figure",),
        note="RMSE against Mitsuba's render with the object: not a measure of the method alone, so not shown "
        "by study run. That render carries light no method models (the point light's highlight on glossy and "
        "mirror objects, the object's shadow and own reflections) and both renders' noise, so the exact traced "
        "row can score worse than a smooth stand-in; truth_at_hit's row gives the part no method can remove "
        "(study/measure/lighting.py says so where it is large). Rank on rmse_truth or relmse_truth_exposed",
    ),
    C("psnr_mitsuba", unit="dB", lower_is_better=HIGH),
    C("ssim_mitsuba", unit="", lower_is_better=HIGH),
    C("flip_mitsuba", unit="", lower_is_better=LOW),
    C(
        "occluded_fraction",
        unit=F,
        views=("figure",),
        note="rays whose exact hit is hidden from o (the case's)",
    ),
    # ------------------------------------------------------------------ the trace and its cost
    C("valid_fraction", unit=F, lower_is_better=HIGH, note="rays the method marked valid"),
    C(
        "ratio_residual_median",
        unit="",
        lower_is_better=LOW,
        note="|distance ratio − 1| at the search's end, median",
    ),
    C(
        "lookups_per_ray",
        unit="lookups",
        lower_is_better=LOW,
        header="lookups",
        views=("run",),
        note="mean cube-map lookups a ray spent",
    ),
    C(
        "lookups_bound",
        unit="lookups",
        lower_is_better=LOW,
        note="the method's bound (what budgets and floors count)",
    ),
    C("rays", unit="count", note="the object's secondary rays"),
    C("backend", note="numpy, llvm or cuda"),
    C(
        "seconds",
        unit="s",
        lower_is_better=LOW,
        note="wall time of the trace (measured, never in a baseline)",
    ),
    # ----------------------------------------------------------- counts and intervals (study.measure.case_columns)
    C("n_rays", unit="count"),
    C(
        "rays_deff",
        note="design effect of wrong_fraction: its variance with rays clustered by pixel over the "
        "binomial variance of independent rays; the fractions' intervals use n_rays / rays_deff rays",
    ),
    C("n_hidden", unit="count"),
    C("n_wrong", unit="count"),
    C(
        "wrong_fraction_texel",
        unit=F,
        lower_is_better=LOW,
        interval=True,
        note="wrong with ε = max(1 cm, one texel at the hit)",
        axis="wrong (> 1 texel)",
    ),
    C(
        "wrong_fraction_1mm",
        unit=F,
        lower_is_better=LOW,
        note="wrong with ε = 1 mm (the same at every resolution)",
    ),
    C("wrong_fraction_3mm", unit=F, lower_is_better=LOW),
    C("wrong_fraction_1cm", unit=F, lower_is_better=LOW, interval=True, axis="wrong (> 1 cm)"),
    C("wrong_fraction_3cm", unit=F, lower_is_better=LOW, interval=True, axis="wrong (> 3 cm)"),
    C("wrong_fraction_10cm", unit=F, lower_is_better=LOW, interval=True, axis="wrong (> 10 cm)"),
    C("wrong_fraction_30cm", unit=F, lower_is_better=LOW),
    C(
        "wrong_fraction_0p5deg",
        unit=F,
        lower_is_better=LOW,
        interval=True,
        note="|shown − exact| subtends > 0.5° from the shading point",
    ),
    C("angle_dropped", unit=F, note="rays without a finite angle (no hit), left out of angle_*"),
    C("dist_dropped", unit=F, note="rays without a finite distance, left out of dist_*"),
    C(
        "angle_p95_all_deg",
        unit="deg",
        lower_is_better=LOW,
        note="angle p95 counting rays without a hit as infinite",
        domain=(0.0, math.inf),
    ),
    C("offscreen_fraction", unit=F, note="rays whose exact hit lies outside the camera's frame"),
    C(
        "wrong_fraction_offscreen",
        unit=F,
        lower_is_better=LOW,
        note="wrong among those (what screen-space methods cannot show)",
    ),
    C("flip_oracle_p95", unit="", lower_is_better=LOW),
    C(
        "rmse_truth",
        unit="linear RGB",
        lower_is_better=LOW,
        header="RMSE truth",
        views=("run",),
        interval=True,
        note="RMSE against truth_at_hit",
        axis="RMSE vs truth_at_hit",
    ),
    C("psnr_truth", unit="dB", lower_is_better=HIGH),
    C("ssim_truth", unit="", lower_is_better=HIGH),
    C(
        "flip_truth",
        unit="",
        lower_is_better=LOW,
        header="FLIP truth",
        views=("run", "figure"),
        interval=True,
        note="LDR-FLIP against truth_at_hit, mean",
    ),
    C("flip_truth_p95", unit="", lower_is_better=LOW),
    C("flip_mitsuba_p95", unit="", lower_is_better=LOW),
    C(
        "rmse_truth_debiased",
        unit="linear RGB",
        lower_is_better=LOW,
        interval=True,
        note="√max(0, RMSE² − σ²): the truth's noise out",
        axis="image RMSE against the truth, debiased",
        log_floor=1e-4,
    ),
    C(
        "relmse_truth",
        unit="",
        lower_is_better=LOW,
        interval=True,
        note="relative MSE, (img − ref)² / (ref² + ε), ε = 0.01 absolute",
    ),
    C(
        "relmse_truth_exposed",
        unit="",
        lower_is_better=LOW,
        header="relMSE exp.",
        views=("run",),
        interval=True,
        note="relMSE after exposure: images × 2^truth_exposure_ev, then (img − ref)² / (ref² + ε), ε = 0.01 (√ε about "
        "half of middle grey: darker pixels count about absolutely, so their noise cannot dominate); the same for a "
        "scene × k, so it ranks methods alike in dark and bright scenes (study/measure/exposure.py); the summary "
        "ranks image error on it",
    ),
    C(
        "truth_noise_relmse",
        unit="",
        note="the truth's own noise in relmse_truth_exposed's unit: its part of every row's",
    ),
    C(
        "truth_exposure_ev",
        unit="EV",
        note="exposure of the truth over the object's pixels (median → 0.18, p95 ≤ 1)",
    ),
    C(
        "firefly_fraction",
        unit=F,
        lower_is_better=LOW,
        note="pixels of Mitsuba's render whose displayed luminance (its exposure, clipped at 1) differs between "
        "its two seeds by > 0.25: over 0.02 the picture is labelled FIREFLIES",
    ),
    C(
        "own_light_share",
        unit=F,
        note="the file's own lights' power over study's point light's (luminance, W); under 0.05 they are weak and "
        "study's point light is added unless light.enabled is given (study/scene/lights.py); NaN: not judged",
        domain=(0.0, FINITE),
    ),
    # worth looking at (study/measure/worth.py): past its limit, `study run` names the cause and the key to change
    C(
        "black_share",
        unit=F,
        lower_is_better=LOW,
        note="Mitsuba's picture shown black after its exposure (at most 8 EV of boost); > 0.5",
    ),
    C(
        "clipped_share",
        unit=F,
        lower_is_better=LOW,
        note="Mitsuba's picture clipped white after its exposure; > 0.1",
    ),
    C("object_share", unit=F, note="the frame's pixels fully on the object; < 0.02"),
    C(
        "mirrored_void",
        unit=F,
        lower_is_better=LOW,
        note="the object's rays that leave the scene (no sky given: black); > 0.5",
    ),
    C(
        "reference_seen",
        unit=F,
        note="the object's bounding sphere as seen unblocked from the reference point; < 0.5",
    ),
    C(
        "own_shadow",
        unit=F,
        note="the object's rays whose exact hit lies in the object's own shadow from the point light: Mitsuba's "
        "render is darker there than truth_at_hit (taken without the object); NaN: no point light",
    ),
    C("truth_noise_rmse", unit="linear RGB", note="the truth's own noise σ"),
    C(
        "truth_noise_flag",
        note="1 where the truth's noise σ exceeds a third of the debiased error it measures (Whittle et al. 2017)",
    ),
    C(
        "rmse_mitsuba_debiased",
        unit="linear RGB",
        lower_is_better=LOW,
        note="rmse_mitsuba less Mitsuba's noise (rmse_mitsuba's caveat holds)",
    ),
    C("mitsuba_noise_rmse", unit="linear RGB", note="Mitsuba's own noise σ over the same pixels"),
    C("mitsuba_noise_flag", note="1 where Mitsuba's noise σ exceeds a third of rmse_mitsuba_debiased"),
    C(
        "mitsuba_noise_frame",
        unit="linear RGB",
        note="Mitsuba's noise over the whole frame (1.4826 × median |half the seeds' difference|): tight over "
        "seeds, so `study check` sees a render at half its samples",
    ),
    C("n_pixels", unit="count"),
    C(
        "n_blocks",
        unit="count",
        note="pixel blocks resampled for the pixel intervals (tables before corr_px)",
    ),
    C(
        "corr_px",
        unit="px",
        note="correlation length of the squared error over the pixels (autocorrelation 1/e); the "
        "pixel intervals sum its covariance over a lag window that follows it",
    ),
    C(
        "rmse_truth_trim",
        unit="linear RGB",
        lower_is_better=LOW,
        note="RMSE without the worst 0.1 % of pixels",
    ),
    C("rmse_truth_debiased_trim", unit="linear RGB", lower_is_better=LOW),
    C("sqerr_top_share_truth", unit=F, note="share of the squared error the worst 0.1 % of pixels carry"),
    # ------------------------------------------------------------------ the error split (study.measure.split)
    C("held_pixels", unit="count", note="object pixels whose every hit the views hold"),
    C("unheld_pixels", unit="count"),
    C("held_fraction", unit=F, note="rays whose exact hit o's views hold (reference rows)"),
    C(
        "dec_total",
        unit="MSE",
        lower_is_better=LOW,
        interval=True,
        note="the split's total: MSE against the truth",
    ),
    C(
        "dec_search",
        unit="MSE",
        lower_is_better=LOW,
        interval=True,
        note="the search's share (method vs oracle on held pixels); NaN on the exact rows",
    ),
    C("dec_visibility", unit="MSE", lower_is_better=LOW, interval=True),
    C("dec_representation", unit="MSE", lower_is_better=LOW, interval=True),
    C("dec_noise", unit="MSE", lower_is_better=LOW, interval=True),
    C("dec_cross", unit="MSE", interval=True),
    C("dec_residual", unit="MSE", interval=True),
    C("dec_sums", unit=F, note="Σ terms / total", domain=(-math.inf, math.inf)),
    C(
        "dec_representation_direct",
        unit="MSE",
        lower_is_better=LOW,
        interval=True,
        note="the map's share measured against the truth: oracle vs truth_at_hit on held pixels, noise removed",
    ),
    C(
        "dec_sums_direct",
        unit=F,
        note="search + visibility + representation_direct + noise meet the total",
        domain=(-math.inf, math.inf),
    ),
    C("rmse_truth_held", unit="linear RGB", lower_is_better=LOW, interval=True),
    C("rmse_truth_unheld", unit="linear RGB", lower_is_better=LOW, interval=True),
    C(
        "radiance_bias_truth",
        unit="ratio − 1",
        note="signed: Σ radiance / Σ truth_at_hit's − 1 over the held object pixels (study.measure.bias); a method "
        "3 % too bright reads +0.03 whatever its search",
    ),
    C(
        "surface_mismatch",
        note="1: the method does not model the object's surface (scored with --allow-mismatch)",
    ),
]
