"""The scaling studies (``scaling-<tag>.csv``): cost of the ``focus`` method (the paper's ``localized``, at its
defaults unless its knob is the variable) and of the exact tracers as one thing grows.

    rays      : synthetic batches of ``ray_counts`` rays (Embree and Mitsuba as well)
    knob      : the focus method at every value of its knob's ladder plus ``knob_extra`` (none without a knob)
    cube_res  : impostor cube resolutions (backends other than numpy, if any)
    triangles : the room plus a displaced heightfield of ``triangles`` triangles over the floor (built here only,
                not a scene key), on the synthetic and the close-up batch; the exact tracers as well
numpy is timed on at most ``numpy_max_rays`` rays (and skipped beyond 4× that in the rays study).
"""

from __future__ import annotations

import math

from study import backend as backends
from study import methods as registry
from study.bench.batches import closeup_rays, distance_texels, room_triangles, synthetic_rays
from study.bench.timing import Exact, mitsuba_variant, rate_row, time_method
from study.measure.inputs import env_info

#: ``opt`` below: the bench's options, a :class:`study.bench.run.BenchOptions` (not imported: ``run`` imports this
#: module, and study's import graph has no cycle, not even through a type annotation).


def knob_values(opt) -> list:
    """Values of the knob study: the focus method's ladder and ``opt.knob_extra``, sorted; each one checked
    (an invalid value is a StudyError). Empty for a method without a knob."""
    m = registry.make(opt.focus)
    if m.knob is None:
        return []
    values = sorted(set(m.knob.ladder) | set(opt.knob_extra))
    for v in values:
        m.with_knob(v)
    return values


def scaling_rows(scene, opt, names, o, tex, exact: Exact, log) -> list[dict]:
    """Cost (ms per call) vs rays, knob value, cube resolution, triangles; numpy only up to numpy_max_rays."""
    rows = []
    fast = [n for n in names if n != "numpy"]
    focus = registry.make(opt.focus)
    info = env_info(scene)
    repeats = max(3, opt.repeats // 2)

    def method_row(study, value, nm, m, t_tex, b, cube):
        k = len(b.x) if nm != "numpy" else opt.numpy_max_rays
        x, R = b.x[:k] - o, b.R[:k]
        t = time_method(m, backends.get(nm), t_tex, x, R, frozen=nm != "numpy", repeats=repeats, info=info)
        rows.append(
            rate_row(
                {"study": study, "value": value, "backend": nm, "label": m.label, "cube_res": cube}, t, len(x)
            )
        )

    def exact_rows(study, value, ex, b):
        rows.append(
            rate_row(
                {"study": study, "value": value, "backend": "embree", "label": "exact: Embree"},
                ex.embree(b),
                len(b.x),
            )
        )
        for dev in sorted({"cuda" if nm == "cuda" else "llvm" for nm in names}):
            t = ex.mitsuba(b, mitsuba_variant(dev))
            if math.isfinite(t):  # NaN: the variant is missing here
                rows.append(
                    rate_row(
                        {
                            "study": study,
                            "value": value,
                            "backend": f"mitsuba-{dev}",
                            "label": "exact: Mitsuba",
                        },
                        t,
                        len(b.x),
                    )
                )

    # ------------------------------------------------------------------ rays
    for n in opt.ray_counts:
        b = synthetic_rays(scene, n, seed=1)
        for nm in names:
            if nm == "numpy" and n > opt.numpy_max_rays * 4:
                continue
            method_row("rays", n, nm, focus, tex, b, opt.cube_res)
        exact_rows("rays", n, exact, b)
        log(f"scaling: {n} rays")
    # ------------------------------------------------------------------ the focus method's knob
    b = synthetic_rays(scene, opt.synthetic, seed=2)
    for v in knob_values(opt):
        m = focus.with_knob(v)
        for nm in names:
            method_row("knob", v, nm, m, tex, b, opt.cube_res)
    log(f"scaling: {focus.knob.param if focus.knob else 'no knob'} of {focus.name}")
    # ------------------------------------------------------------------ cube resolution
    for res in opt.cube_resolutions:
        t_tex = distance_texels(exact.tracer, o, res)
        for nm in fast or names:
            method_row("cube_res", res, nm, focus, t_tex, b, res)
    log("scaling: cube resolution")
    # ------------------------------------------------------------------ scene complexity (random and coherent rays)
    close = closeup_rays(scene, opt.position, opt.scene_res)
    for extra in opt.triangles:
        V, F = room_triangles(scene, extra)
        ex = Exact(V, F, repeats, log)
        t_tex = distance_texels(ex.tracer, o, opt.cube_res)
        for bb, kind in ((b, "synthetic"), (close, "close-up")):
            n0 = len(rows)
            exact_rows("triangles", len(F), ex, bb)
            for nm in fast or names:
                method_row("triangles", len(F), nm, focus, t_tex, bb, opt.cube_res)
            for r in rows[n0:]:
                r["label"] += f" ({kind})"
        log(f"scaling: {len(F)} triangles")
    return rows
