"""The rows of the declared column table (:mod:`study.columns`): one :class:`TableColumn` per column of a results
table — name, unit, direction, views, interval, axis label, log floor, what it means — and the views' orders.
"""

from __future__ import annotations

import math
import sys
from dataclasses import KW_ONLY, dataclass, replace

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
    _: KW_ONLY
    #: the axis label of every plot that draws it (one spelling; the pareto page adds "(median over cases)")
    axis: str = ""
    #: on a log axis, values at or below it are drawn at it (marked, not hidden); None: no floor of its own
    log_floor: float | None = None


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
        axis="median angular error (deg)",
        log_floor=1e-6,
    ),
    C(
        "angle_p95_deg",
        "deg",
        LOW,
        views=("figure",),
        interval=True,
        axis="p95 angular error (deg)",
        log_floor=1e-6,
    ),
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
        axis="fraction of wrong rays",
        log_floor=1e-4,
    ),
    C("wrong_depth_fraction", F, LOW, note="wrong, on the exact hit's own surface but at another depth"),
    C("wrong_surface_fraction", F, LOW, note="wrong, on another surface"),
    C("no_hit_fraction", F, LOW, note="the method answered no point"),
    C(
        "wrong_fraction_visible",
        F,
        LOW,
        "wrong vis.",
        ("run",),
        True,
        "wrong among rays whose hit o sees",
        axis="wrong (> 1 texel), hits o sees",
    ),
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
    C(
        "wrong_fraction_texel",
        F,
        LOW,
        interval=True,
        note="wrong with ε = max(1 cm, one texel at the hit)",
        axis="wrong (> 1 texel)",
    ),
    C("wrong_fraction_1mm", F, LOW, note="wrong with ε = 1 mm (the same at every resolution)"),
    C("wrong_fraction_3mm", F, LOW),
    C("wrong_fraction_1cm", F, LOW, interval=True, axis="wrong (> 1 cm)"),
    C("wrong_fraction_3cm", F, LOW, interval=True, axis="wrong (> 3 cm)"),
    C("wrong_fraction_10cm", F, LOW, interval=True, axis="wrong (> 10 cm)"),
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
    C(
        "rmse_truth",
        "linear RGB",
        LOW,
        "RMSE truth",
        ("run",),
        True,
        "RMSE against truth_at_hit",
        axis="RMSE vs truth_at_hit",
    ),
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
        axis="image RMSE against the truth, debiased",
        log_floor=1e-4,
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
    "convergence": ["wrong_fraction_texel", "wrong_fraction_visible", "wrong_fraction_1cm", "wrong_fraction_3cm",
                    "wrong_fraction_10cm", "angle_p95_deg", "rmse_truth"],
}  # fmt: skip
#: a row is in each view that :data:`ORDER` lists it in (the view's order is ORDER's): marked here once
TABLE[:] = [
    replace(c, views=c.views + tuple(v for v, names in ORDER.items() if c.name in names and v not in c.views))
    for c in TABLE
]
