"""Timing: one harness (:func:`median_time`) for the methods (per backend, frozen or plain) and the exact tracers.

Warm-up calls first (compilation, recording); then ``repeats`` repeats of ``inner`` back-to-back calls (``inner``
chosen so one repeat lasts ≥ 20 ms), each call's outputs evaluated, the device synchronised (``dr.sync_thread()``)
before the clock is read; the median per call is reported.

Exact tracers: Embree (:class:`study.reference.embree.Tracer`, chunks cast on every core: embreex releases the GIL)
and Mitsuba's ray queries (:data:`QUERIES`: full ``ray_intersect``, ``ray_intersect_preliminary``, ``ray_test``;
``llvm_ad_rgb`` on the CPU, ``cuda_ad_rgb``/OptiX on the GPU), all on the same triangles; :class:`Exact`
times each batch once and shares the numbers between tables.
"""

from __future__ import annotations

import copy
import dataclasses
import gc
import math
import time
from types import SimpleNamespace

import numpy as np

from study.impostor import probes
from study.impostor.envmap import EnvMap
from study.impostor.probes import ProbeSet
from study.impostor.screen import ScreenView, depth_buffer
from study.impostor.sdf import room_field
from study.impostor.views import Captured
from study.methods.ssr_hiz import hiz_of
from study.reference import mitsuba as mitsuba_ref
from study.reference.embree import Tracer

FRAME = 1024 * 1024  # rays of a 1024² frame


def median_time(call, finish, *, repeats: int, warmup: int = 2, min_repeat_s: float = 0.02) -> float:
    """Median seconds per ``call()``; ``finish(out)`` evaluates one call's outputs, ``finish(None)`` syncs.

    ``inner`` calls per repeat (each evaluated), one device sync before each clock read."""
    for _ in range(warmup):
        finish(call())
        finish(None)
    t0 = time.perf_counter()
    finish(call())
    finish(None)
    once = time.perf_counter() - t0
    inner = max(1, min(1000, int(min_repeat_s / max(once, 1e-7))))
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            finish(call())
        finish(None)
        ts.append((time.perf_counter() - t0) / inner)
    return float(np.median(ts))


def ms_per_frame(seconds: float, rays: int) -> float:
    """Milliseconds for a 1024² frame at the rate of ``rays`` in ``seconds``."""
    return seconds / rays * FRAME * 1e3


def rate_row(base: dict, seconds: float, rays: int) -> dict:
    """``base`` plus rays, ms_per_call, mrays_per_s and ms_per_frame (a 1024² frame at the measured rate)."""
    return {
        **base,
        "rays": rays,
        "ms_per_call": seconds * 1e3,
        "mrays_per_s": rays / seconds / 1e6,
        "ms_per_frame": ms_per_frame(seconds, rays),
    }


# ---------------------------------------------------------------------------------------------- methods
def camera_depth(camera, tracer: Tracer) -> np.ndarray:
    """The (H, W) z-depth buffer of ``camera`` (a scene's camera) into the bench's triangles (no object)."""
    return depth_buffer(SimpleNamespace(camera=camera), tracer)


def bench_screen(depth: np.ndarray, camera, reference, B) -> ScreenView:
    """The camera's buffer for the screen-space methods: ``depth`` and a stand-in colour (zeros: what a fetch costs
    does not depend on texel values), its Hi-Z pyramid built here, outside any recording."""
    scr = ScreenView(depth, np.zeros(depth.shape + (3,), np.float32), camera, reference, B)
    hiz_of(scr)
    return scr


def bench_probes(spec, tracer, tex_np: np.ndarray, reference, room, B) -> ProbeSet:
    """The probe set ``spec`` for the probe methods (``multi_probe``, ``probe_blend``): probe 0 the impostor
    ``tex_np``, the others placed in ``room`` as a case places them (:func:`study.impostor.probes.probe_points`),
    their distances traced by ``tracer`` (a search's steps depend on them), their colour the impostor's (what a
    fetch costs does not depend on texel values); its min pyramid built here, outside any recording."""
    pts = probes.probe_points(spec, room, tracer)
    res = tex_np.shape[1]
    texels = [tex_np] + [probes.probe_texels(tracer, p, res, tex_np[..., :3]) for p in pts]
    o = np.asarray(reference, float)
    ps = ProbeSet.around(
        np.stack(texels).astype(np.float32), np.concatenate([o[None], pts.reshape(-1, 3)]), o, B
    )
    ps.pyramid  # noqa: B018  built now
    return ps


def method_runner(
    m, B, tex_np, x, R, *, frozen: bool, info: dict | None = None, screen=None, probe_sets: dict | None = None
):
    """(call, finish) for one method on one backend: call() traces (or replays) and returns the outputs.

    The method gets a :class:`~study.impostor.views.Captured` with ``info``, the scene knowledge (``reference``,
    ``room``), and with ``fallback`` set: a method that searches several layers gets a copy of the impostor as each
    layer (the bench times lookups; texel values do not change their cost), so its textures still come in through
    the frozen function's arguments; the probe sets the method asks for are ``probe_sets`` (:func:`bench_probes`;
    one missing: the impostor as the only probe), their textures and pyramids arguments too; the camera's buffer
    is ``screen`` (:func:`bench_screen`; None: every ray of ``ssr`` and ``ssr_hiz`` goes to their fallbacks), its
    texture and Hi-Z pyramid arguments too; a distance field is the room box's
    (:func:`study.impostor.sdf.room_field`: the cost of a 3D fetch does not depend on the values), its texture an
    argument too."""
    env = EnvMap(tex_np, B)
    pyramid = env.pyramid  # built here, outside the recording; its data comes in through the arguments
    # the layer shares env's textures (a shallow copy): a texture of its own, replaced inside the recording below,
    # would be freed there — an unrecordable host call that aborts the process
    layer = copy.copy(env) if m.layers_needed() > 1 else None
    views = Captured(
        impostor=env, layers=(layer,) * m.layers_needed() if layer else (), fallback=True, **(info or {})
    )
    # distance fields: the room box's (made here, outside the recording; their textures come in as arguments)
    fields = [room_field(views, spec) for spec in m.views_needed().sdfs]
    if fields:
        views = dataclasses.replace(views, sdfs=dict(zip(m.views_needed().sdfs, fields)))
    sets = {spec: (probe_sets or {})[spec] for spec in m.views_needed().probes if spec in (probe_sets or {})}
    if sets:
        views = dataclasses.replace(views, probes=sets)
    scr = screen if screen is not None and m.views_needed().screen else None
    hz = hiz_of(scr) if scr is not None else None  # (bound either way: a frozen function reads its closure)
    if scr is not None:
        views = dataclasses.replace(views, screen=scr)
    X, RR = B.vec(x), B.vec(R)
    B.eval(X.x, X.y, X.z, RR.x, RR.y, RR.z)

    def trace(
        tex, dist, pyr, X, RR, vol, on_screen, on_probes
    ):  # textures as arguments: a frozen function sees only those
        env.tex, env.dist, pyramid.data = tex, dist, pyr
        if scr is not None:
            scr.tex, hz.data = on_screen
        for ps, (ptex, pdist, ppyr) in zip(sets.values(), on_probes):
            ps.tex, ps.dist, ps.pyramid.data = ptex, pdist, ppyr
        if layer is not None:
            layer.tex, layer.dist = tex, dist
        for f, t in zip(fields, vol):
            f.tex = t
        t = m.trace(B, views, X, RR)
        spent = t.lookups if t.lookups is not None else X.x * 0.0 + m.lookup_bound(env.res)
        return t.shown, t.radiance, t.ratio, t.valid, spent

    fn = B.freeze(trace) if frozen else trace
    tex, dist = env.tex, env.dist
    vol = [f.tex for f in fields]

    def finish(out):
        if out is None:
            B.sync()
        else:
            s, r, ratio, valid, spent = out
            B.eval(s.x, s.y, s.z, r.x, r.y, r.z, ratio, valid, spent)

    pyr = pyramid.data
    on_screen = (scr.tex, hz.data) if scr is not None else ()
    on_probes = tuple((ps.tex, ps.dist, ps.pyramid.data) for ps in sets.values())
    return (lambda: fn(tex, dist, pyr, X, RR, vol, on_screen, on_probes)), finish


def kernel_seconds(dr, call, finish, *, repeats: int) -> float:
    """Median seconds per ``call()`` that the device spent in Dr.Jit's kernels (its kernel history: CUDA events
    on the GPU; Mitsuba's ray queries are Dr.Jit kernels too), without the host's share (tracing or replaying,
    launching); NaN where ``dr`` is None (numpy). A short kernel's wall time is bound by the host: localized(10)'s
    0.05 ms on one H200 measured 0.05–0.14 ms by the clock."""
    if dr is None:
        return math.nan
    finish(call())
    finish(None)
    flag = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        ts = []
        for _ in range(repeats):
            dr.kernel_history()  # clears it
            finish(call())
            finish(None)
            ms = [
                k.get("execution_time", 0.0)
                for k in dr.kernel_history()
                if k.get("type") == dr.KernelType.JIT
            ]
            ts.append(sum(ms) * 1e-3)
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, flag)
    return float(np.median(ts))


def time_method(
    m,
    B,
    tex_np,
    x,
    R,
    *,
    frozen: bool,
    repeats: int,
    info: dict | None = None,
    spent: list | None = None,
    kernel: list | None = None,
    screen=None,
    probe_sets: dict | None = None,
) -> float:
    """Median seconds per call of ``m`` on the rays; with ``spent``, the mean lookups per ray that the calls
    measured (``Trace.lookups``) is appended to it; with ``kernel``, the seconds per call spent in the device's
    kernels (:func:`kernel_seconds`)."""
    # Garbage left by earlier runs (reference cycles) must not be freed while a frozen function records:
    # freeing Dr.Jit memory then is an unrecordable host call that aborts the process.
    gc.collect()
    B.sync()
    gc.disable()
    try:
        call, finish = method_runner(
            m, B, tex_np, x, R, frozen=frozen, info=info, screen=screen, probe_sets=probe_sets
        )
        last = []

        def kept():
            last[:] = [call()]
            return last[0]

        seconds = median_time(kept, finish, repeats=repeats)
        if kernel is not None:
            kernel.append(kernel_seconds(getattr(B, "dr", None), kept, finish, repeats=repeats))
        if spent is not None:
            spent.append(float(np.mean(B.numpy(last[0][4]))))
        return seconds
    finally:
        gc.enable()


# ---------------------------------------------------------------------------------------------- exact tracers
def time_embree(tracer: Tracer, x, R, *, repeats: int) -> float:
    o, d = np.ascontiguousarray(x, np.float32), np.ascontiguousarray(R, np.float32)
    return median_time(lambda: tracer.distance(o, d), lambda out: None, repeats=repeats)


#: Mitsuba's ray queries, dearest first: the full SurfaceInteraction, the hit distance (and primitive) only, and
#: occlusion only — the cheapest exact answer to "where is the first hit" is ``ray_intersect_preliminary``.
QUERIES = ("ray_intersect", "ray_intersect_preliminary", "ray_test")


def time_mitsuba(
    m, scene, x, R, *, repeats: int, query: str = "ray_intersect", kernel: list | None = None
) -> float:
    """Median seconds per ``query`` of the rays; with ``kernel``, the kernels' device time per query is appended
    to it (:func:`kernel_seconds`)."""
    import drjit as dr  # optional: only where Mitsuba is timed

    ray = m.Ray3f(
        m.Point3f(np.ascontiguousarray(x.T, np.float32)), m.Vector3f(np.ascontiguousarray(R.T, np.float32))
    )
    dr.eval(ray)
    fn = getattr(scene, query)

    def finish(out):
        if out is None:
            dr.sync_thread()
        elif query == "ray_intersect":
            dr.eval(out.t, out.p)
        elif query == "ray_intersect_preliminary":
            dr.eval(out.t, out.prim_index)
        else:
            dr.eval(out)

    seconds = median_time(lambda: fn(ray), finish, repeats=repeats)
    if kernel is not None:
        kernel.append(kernel_seconds(dr, lambda: fn(ray), finish, repeats=repeats))
    return seconds


#: What a renderer does at the exact hit besides finding it (``traced``'s shading, :func:`time_shading`): the
#: material evaluated towards the point light with the light's falloff, and the shadow ray to the light.
SHADING = ("shade_material", "shadow_ray")


def time_shading(
    m, scene, x, R, light: tuple, *, repeats: int, kernel: list | None = None
) -> dict[str, float]:
    """Median seconds per call of the shading a renderer does at the rays' exact hits (:data:`SHADING`), on the
    hits of ``scene.ray_intersect`` (computed once, not timed): ``shade_material`` evaluates the hit's BSDF
    (Mitsuba's ``eval``, cosine included) towards the point light ``light`` = (position, intensity) with its
    inverse-square falloff; ``shadow_ray`` casts the hit's shadow ray to the light (``ray_test``). With ``kernel``,
    a dict of the same keys → the kernels' device time per call is appended to it (:func:`kernel_seconds`)."""
    import drjit as dr  # optional: only where Mitsuba is timed

    ray = m.Ray3f(
        m.Point3f(np.ascontiguousarray(x.T, np.float32)), m.Vector3f(np.ascontiguousarray(R.T, np.float32))
    )
    si = scene.ray_intersect(ray)
    dr.eval(si)
    valid = si.is_valid()
    pos, intensity = light
    L, I = m.Point3f(*map(float, pos)), m.Color3f(*map(float, intensity))
    ctx = m.BSDFContext()

    def material():
        to = L - si.p
        d2 = dr.squared_norm(to)
        wo = si.to_local(to * dr.rsqrt(d2))
        f = si.bsdf(ray).eval(ctx, si, wo, valid)
        return dr.select(valid, f * I / d2, 0.0)

    def shadow():
        return scene.ray_test(si.spawn_ray_to(L), valid)

    def finish(out):
        if out is None:
            dr.sync_thread()
        else:
            dr.eval(out)

    out, kern = {}, {}
    for name, fn in zip(SHADING, (material, shadow)):
        out[name] = median_time(fn, finish, repeats=repeats)
        kern[name] = kernel_seconds(dr, fn, finish, repeats=repeats)
    if kernel is not None:
        kernel.append(kern)
    return out


def mitsuba_variant(backend: str) -> str:
    """The Mitsuba variant on the device of ``backend``: CUDA for cuda, LLVM for numpy and llvm."""
    return "cuda_ad_rgb" if backend == "cuda" else "llvm_ad_rgb"


class Exact:
    """Embree and Mitsuba timings of batches on one set of triangles (V, F), each computed once and shared.

    ``tracer`` is the Embree tracer of (V, F) (also what the bench's impostor is captured with)."""

    def __init__(self, V, F, repeats: int, log):
        self.V, self.F, self.repeats, self.log = V, F, repeats, log
        self.tracer = Tracer.from_triangles(V, F)
        self.scenes: dict[str, tuple] = {}
        self.t: dict[tuple, float] = {}
        self.kernel_t: dict[tuple, float] = {}  # the same queries' kernel time (Mitsuba's only)

    def embree(self, batch) -> float:
        key = ("embree", batch.name)
        if key not in self.t:
            self.t[key] = time_embree(self.tracer, batch.x, batch.R, repeats=self.repeats)
        return self.t[key]

    def mitsuba(self, batch, variant: str, query: str = "ray_intersect") -> float:
        """Seconds per ``query`` (one of :data:`QUERIES`) of the batch in ``variant``; NaN (and a log line) where
        it is missing."""
        key = (variant, batch.name, query)
        if key not in self.t:
            try:
                if variant not in self.scenes:
                    self.scenes[variant] = mitsuba_ref.triangle_scene(self.V, self.F, variant)
                m, sc = self.scenes[variant]
                mitsuba_ref.mi(variant)  # the variant current while its scene is timed
                kern: list = []
                self.t[key] = time_mitsuba(
                    m, sc, batch.x, batch.R, repeats=self.repeats, query=query, kernel=kern
                )
                self.kernel_t[key] = kern[0]
            except Exception as err:  # a variant missing on this machine: no number, say why
                self.log(f"mitsuba {variant} unavailable: {str(err).splitlines()[0][:120]}")
                self.t[key] = self.kernel_t[key] = math.nan
        return self.t[key]

    def shading(self, batch, variant: str, light: tuple) -> tuple[dict, dict]:
        """(seconds, kernel seconds) per call of each part of :data:`SHADING` at the batch's exact hits in
        ``variant``, the point light ``light`` = (position, intensity); NaNs (and a log line) where missing."""
        key = (variant, batch.name, "shading")
        if key not in self.t:
            try:
                if variant not in self.scenes:
                    self.scenes[variant] = mitsuba_ref.triangle_scene(self.V, self.F, variant)
                m, sc = self.scenes[variant]
                mitsuba_ref.mi(variant)
                kern: list = []
                self.t[key] = time_shading(m, sc, batch.x, batch.R, light, repeats=self.repeats, kernel=kern)
                self.kernel_t[key] = kern[0]
            except Exception as err:  # a variant missing on this machine: no number, say why
                self.log(f"mitsuba {variant} shading unavailable: {str(err).splitlines()[0][:120]}")
                self.t[key] = self.kernel_t[key] = dict.fromkeys(SHADING, math.nan)
        return self.t[key], self.kernel_t[key]

    def mitsuba_kernels(self, batch, variant: str, query: str = "ray_intersect") -> float:
        """Seconds per ``query`` spent in the device's kernels (:func:`kernel_seconds`); NaN where missing."""
        self.mitsuba(batch, variant, query)
        return self.kernel_t[(variant, batch.name, query)]
