"""The built-in column groups of a results row as producers over one trace's case context (:class:`RayContext`),
each declaring the columns it writes, as a plug-in's producer does (:mod:`study.measure.producers`).

In the order a row holds them: the case's own columns, the trace's identity and knobs, the geometry of the shown
point, the outcome classes (:mod:`study.measure.outcomes`), their counts, fixed tolerances and ray intervals
(:mod:`study.measure.case_columns`), the off-screen hits, the image errors (measured for all the case's traces
together, :mod:`study.measure.batched`, and handed in; blank on the exact rows), the references' own; after the
plug-ins' producers: the method's flags and the search's cost. What depends only on the case (its own columns, each
ray's pixel, the held hits) is computed once per case and handed in with the context, never per trace. A column a
group declares is one no plug-in may write (an error when it registers).
"""

from __future__ import annotations

import numpy as np

from study import columns
from study.measure import case_columns, metrics, outcomes, split
from study.measure.producers import AFTER, GROUPS, PRODUCERS, RayContext, _produced, group

#: the per-ray columns of the geometry, the outcome classes and the counts and fixed tolerances
_GEOMETRY = ("angle_median_deg", "angle_p95_deg", "angle_max_deg", "dist_median")
_OUTCOMES = ("correct_fraction", "wrong_fraction", "wrong_depth_fraction", "wrong_surface_fraction", "no_hit_fraction",
             "wrong_fraction_visible", "wrong_fraction_hidden", "hidden_fraction", "dist_p50", "dist_p95", "dist_p99",
             "depth_error_p95", "angle_p95_visible_deg", "angle_p95_hidden_deg")  # fmt: skip
_COUNTS = ("n_rays", "n_hidden", "n_wrong", "wrong_fraction_texel", "wrong_fraction_1mm", "wrong_fraction_3mm",
           "wrong_fraction_1cm", "wrong_fraction_3cm", "wrong_fraction_10cm", "wrong_fraction_30cm",
           "wrong_fraction_0p5deg", "rays_deff", "angle_dropped", "dist_dropped", "angle_p95_all_deg")  # fmt: skip
#: the case's own columns, the same in each of its rows (case._base_columns: position, lights, worth looking at)
_CASE = ("case", "cube_res", "object_x", "object_y", "object_z", "object_alpha", "backend", "displacement", "rays",
         "occluded_fraction", "own_light_share", "black_share", "clipped_share", "object_share", "mirrored_void",
         "reference_seen", "own_shadow")  # fmt: skip
#: the image columns (case._image_columns, batched.method_columns): per reference, the truth's own, the pixel
#: intervals' counts and robust errors, the error split, the radiance bias
_IMAGE = (
    *(f"{m}_{r}" for r in ("oracle", "truth", "mitsuba") for m in ("rmse", "psnr", "ssim", "flip")),
    *(f"flip_{r}_p95" for r in ("oracle", "truth", "mitsuba")),
    "rmse_truth_debiased", "relmse_truth", "truth_noise_rmse", "truth_noise_flag", "rmse_mitsuba_debiased",
    "mitsuba_noise_rmse", "mitsuba_noise_flag", "mitsuba_noise_frame", "relmse_truth_exposed", "truth_noise_relmse",
    "truth_exposure_ev", "firefly_fraction", "n_pixels", "n_blocks", "corr_px", "rmse_truth_trim",
    "rmse_truth_debiased_trim", "sqerr_top_share_truth", "held_pixels", "unheld_pixels", "dec_total", "dec_search",
    "dec_visibility", "dec_representation", "dec_noise", "dec_cross", "dec_residual", "dec_sums",
    "dec_representation_direct", "dec_sums_direct", "rmse_truth_held", "rmse_truth_unheld", "radiance_bias_truth",
)  # fmt: skip


def _bounds(*names: str) -> tuple[str, ...]:
    """The calibrated ``_lo``/``_hi`` of those of ``names`` the table gives an interval."""
    return tuple(f"{c}_{e}" for c in names if columns.declared(c).interval for e in ("lo", "hi"))


@group(columns=_CASE)
def case_own(ctx: RayContext) -> dict:
    """The case's own columns (computed once per case and handed in), first in every row; a refracting object's
    ray statistics (``refraction``, ``exit``, …) come with them."""
    return ctx.case_columns or {}


@group(columns=("method", "label", "family", "knob", "knob_value"))
def trace_identity(ctx: RayContext) -> dict:
    """The method's registered name, its label and where its knob places it (``case.knob_columns``)."""
    t = ctx.trace
    return {"method": t.method, "label": t.label, **t.knobs}


@group(columns=_GEOMETRY)
def shown_geometry(ctx: RayContext) -> dict:
    """The angle at the shading point between the shown and the exact hit (median, p95, max over the rays with one)
    and the median distance between them."""
    return {
        **metrics.value_stats(ctx.angle, "angle", "_deg"),
        "dist_median": float(np.nanmedian(np.linalg.norm(ctx.shown - ctx.exact, axis=-1))),
    }


@group(columns=_OUTCOMES)
def outcome_classes(ctx: RayContext) -> dict:
    """The outcome classes' fractions, among the rays o sees and those it does not (:mod:`study.measure.outcomes`)."""
    return outcomes.outcome_columns(ctx.classes, ctx.occluded, ctx.angle)


@group(columns=_COUNTS + _bounds(*_GEOMETRY, *_OUTCOMES, *_COUNTS))
def ray_intervals(ctx: RayContext) -> dict:
    """Counts, fixed tolerances and the calibrated intervals over the rays, clustered by pixel (each ray's pixel
    taken once per case)."""
    return case_columns.ray_columns(ctx.classes, ctx.angle, ctx.occluded, ctx.x, ctx.exact, pixels=ctx.pixels,
                                    shape=ctx.rays.hit.shape[:2])  # fmt: skip


@group(columns=("offscreen_fraction", "wrong_fraction_offscreen"))
def offscreen(ctx: RayContext) -> dict:
    """Rays whose exact hit the camera's frame does not show, and the wrong among them."""
    return outcomes.offscreen_columns(ctx.classes, ctx.hits.offscreen)


@group(columns=_IMAGE + _bounds(*_IMAGE))
def image_measures(ctx: RayContext) -> dict:
    """The image against the oracle, the truth and Mitsuba, the truth's own columns, pixel intervals, the error
    split and the radiance bias (names per reference: :func:`study.measure.case._image_columns`), measured for the
    case's traces together and handed in with the context; a trace that reads no cube map (the exact rows,
    ``Method.reads_views``) leaves out its oracle and split columns (:func:`study.measure.split.unread_blank`)."""
    cols = ctx.image_columns or {}
    return cols if ctx.trace is None or ctx.trace.reads_views else split.unread_blank(cols)


@group(columns=("held_fraction",))
def reference_own(ctx: RayContext) -> dict:
    """A reference's row: the share of rays whose exact hit o's views hold."""
    if not ctx.trace.reference:
        return {}
    return {"held_fraction": float(ctx.held.mean()) if len(ctx.held) else np.nan}


@group(after_plugins=True)
def flags(ctx: RayContext) -> dict:
    """The method's declared diagnostics: column → fraction of rays (names its methods declare)."""
    return ctx.trace.flags


@group(columns=("valid_fraction", "ratio_residual_median", "lookups_per_ray", "lookups_bound", "seconds"),
       after_plugins=True)  # fmt: skip
def cost(ctx: RayContext) -> dict:
    """The rays the method marked valid, the search's residual at its end, its lookups per ray against its bound and
    the trace's wall time."""
    t = ctx.trace
    return {
        "valid_fraction": float(t.valid.mean()),
        "ratio_residual_median": float(np.nanmedian(np.abs(t.ratio - 1))),
        "lookups_per_ray": t.lookups,
        "lookups_bound": t.bound,
        "seconds": t.seconds,
    }


def row_of(ctx: RayContext) -> dict:
    """One trace's row: every built-in group's columns and every plug-in producer's, in their order (:data:`GROUPS`,
    :data:`PRODUCERS`, :data:`AFTER`)."""
    row = {}
    for fn in GROUPS:
        row.update(fn(ctx))
    if PRODUCERS:
        row.update(_produced(ctx, taken=ctx.trace.flags if ctx.trace is not None else ()))
    for fn in AFTER:
        row.update(fn(ctx))
    return row
