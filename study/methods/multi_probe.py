"""Tracing through several distance probes (after McGuire et al., "Real-Time Global Illumination using Precomputed
Light Field Probes", I3D 2017, with cube maps of radiance and radial distance): segment by segment, each in a probe
that sees it, switching probe where the segment passes behind a surface that probe sees.

Probes come from ``Captured.probes[spec]`` (:class:`study.impostor.probes.ProbeSet`, N cube maps, probe 0 the
impostor at o; ``spec`` = :class:`~study.impostor.views.ProbeSpec` of ``grid`` / ``points`` / ``clearance``); on a
bare impostor without probes, the impostor is the only probe (a caller that captures views and lacks the set is a
StudyError).

Per ray x + R d (relative to o), starting at d₀ = 0 in the *nearest probe that sees the start point*
(|p − c_k| ≤ |p − c_k|', an undershoot; every probe is tested, N lookups; probe 0 where none does):

1. **march** the segment from x + R d₀ on probe k as ``linear_secant`` does on the impostor (the t = d/(d + a)
   parameterization about the probe's centre c_k, samples in equal angles no farther apart than
   1/``steps_per_texel`` texels, n = ⌈π res steps_per_texel⌉ for a half turn, at most ``max_steps``; with
   ``hierarchical``, the default, blocks of samples that probe k's min pyramid proves in front of its surface are
   skipped, :class:`study.methods.march.Skip`, the same bracket from fewer lookups): the first step from in front
   of probe k's surface to behind it, then ``secant_steps`` Illinois steps → the crossing l (relative to c_k),
   r = |l|.
2. **classify** the crossing by the texels of probe k whose centres are nearest to l and to l̂ turned by ±6/res
   radians along the arc (3 texels at a face's centre, up to 6 at its corners; distances D, D_lo, D_hi, no
   interpolation), τ = ``thickness`` + r·``slack``/res: **UNKNOWN** where the depth *drops* across the crossing
   like a step, D_lo − D_hi > τ and |D_lo + D_hi − 2D| > (D_lo − D_hi)/2 (the crossing lies on the interpolated
   *skin* across a depth jump: the ray passed behind a nearer surface this probe sees, a column's silhouette, and
   what it hits there is hidden from this probe; a surface seen obliquely is a ramp instead, whose second
   difference is small), or where the probe's depth there is not the ray's, |r − D| > τ + |D_hi − D_lo|/4 (the
   ramp's slope allows for the texel's quantization); **HIT** otherwise. **MISS**: no crossing (the ray leaves an
   open environment).
3. on UNKNOWN, d₀ moves to the last sample in front of probe k's surface (that stretch of the ray is free) and the
   trace goes on in the nearest untried probe that sees the new start (N lookups); none left: the ray is resolved
   by the first crossing it found (what a single probe shows), as an engine would shade it.

In a config, ``grid`` and ``points`` are lists and so must be wrapped once more (lists expand into variants):
``{ name = "multi_probe", grid = [[3, 2, 3]] }``, ``points = [[[-0.9, 2.3, -0.9], [1.0, 2.3, 1.0]]]``.

Shown point of a hit: the point probe k holds in the crossing's direction, c_k + l̂·|l|'_k; its radiance is probe
k's (:meth:`MultiProbe.search`). The origin check of :meth:`~study.methods.base.Method.trace` is generalized
(:meth:`MultiProbe.sees_origin`): with it, rays whose origin no probe sees are invalid. Cost, counted per ray for
the rounds it takes (``Trace.lookups``; a GPU thread stops when its ray is resolved): N (choice of the first probe)
+ per round 1 + the march's lookups (n for the texel march, ``hierarchical=False``; what each ray spent for the
hierarchical one) + ``secant_steps`` + 3 (g(0), march, secant, the three nearest texels) + N per switch + 1 (the
shown point); :meth:`MultiProbe.lookups_per_ray` bounds it with N rounds, N the grid's cells (or points) and
probe 0.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor import cubemap
from study.impostor.views import Captured, ProbeSpec, Views
from study.methods.base import Found, Knob, TracingMethod, register
from study.methods.linear_secant import TexelMarchParams, march_bound, march_steps, skipper
from study.methods.search import Bracket, arc_samples, first_crossing, refine, secant_point

Vec3 = tuple[float, float, float]


class ProbeGridParams(BaseModel):
    """Where the probes stand (shared with ``probe_blend``, so one capture serves both): :func:`probe_spec`."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    grid: tuple[
        Annotated[int, Field(ge=1, le=8)],
        Annotated[int, Field(ge=1, le=8)],
        Annotated[int, Field(ge=1, le=8)],
    ] = Field((2, 2, 2), description="probes at the centres of a grid of cells in the environment's bounds")
    points: tuple[Vec3, ...] | None = Field(None, description="or probes at these world points (besides o)")
    clearance: Annotated[
        float, Field(ge=0, le=10, description="grid probes at least this far from surfaces, metres")
    ] = 0.1


class Params(ProbeGridParams, TexelMarchParams):  # steps_per_texel, max_steps, then the probes' place
    secant_steps: Annotated[int, Field(ge=0, le=100, description="Illinois steps on each crossing")] = 4
    thickness: Annotated[float, Field(ge=0, le=10, description="HIT tolerance, metres (+ the slack)")] = 0.05
    slack: Annotated[
        float,
        Field(ge=0, le=64, description="HIT tolerance added per metre of range: r·slack/res (texels of arc)"),
    ] = 4.0


class _Single:
    """The impostor as the only probe (a bare impostor without ``Captured.probes``)."""

    def __init__(self, env):
        self.env, self.B, self.n, self.res = env, env.B, 1, getattr(env, "res", 0)
        self.centres = np.zeros((1, 3))

    @property
    def pyramid(self):  # the impostor's (built on first use); None: an analytic environment
        return getattr(getattr(self.env, "impostor", self.env), "pyramid", None)

    def distance(self, k, v):
        return self.env.distance(v)

    @property
    def dist(self):  # the impostor's distance texture (face coordinates of probe 0: the impostor's)
        return getattr(self.env, "impostor", self.env).dist

    def lookup(self, k, v):
        return self.env.lookup(v)

    def centre(self, k):
        return V3(k * 0.0, k * 0.0, k * 0.0)

    def nearest(self, k, v):
        if not self.res or not hasattr(self.env, "dist"):
            return self.env.distance(v)
        B, R = self.B, float(self.res)
        face, u, w = cubemap.face_uv(B, v.x, v.y, v.z)
        uc = (B.minimum(B.floor(u * R), R - 1.0) + 0.5) / R
        wc = (B.minimum(B.floor(w * R), R - 1.0) + 0.5) / R
        return B.sample(self.env.dist, face, uc, wc)[0]


def _finite(B, v: V3) -> V3:
    """``v`` with non-finite components replaced by 1 (rays already inactive: no lookup may see a NaN)."""
    return V3(*(B.select(B.isfinite(c), c, 1.0) for c in (v.x, v.y, v.z)))


def _sel(B, m, a: V3, b: V3) -> V3:
    return V3(B.select(m, a.x, b.x), B.select(m, a.y, b.y), B.select(m, a.z, b.z))


def _skip(B, P, xs: V3, R: V3, a, n: int, k):
    """The hierarchical march's :class:`~study.methods.march.Skip` on probe k (its faces 6k … 6k + 5 of the stacked
    pyramid; None: an analytic environment), g at its Look made as g(t) makes it (the same bits)."""
    skip = skipper(B, P.pyramid, xs, R, a, n, base=k * 6.0)
    if skip is not None:
        skip.value = lambda L: L.length - L.rest * B.sample(P.dist, L.face, L.u, L.v)[0]
    return skip


def probe_spec(p) -> ProbeSpec:
    """The probe set a method's parameters name (``grid``, ``points``, ``clearance``)."""
    pts = tuple(tuple(float(c) for c in q) for q in p.points) if p.points is not None else None
    return ProbeSpec(grid=tuple(p.grid), points=pts, clearance=p.clearance)


@register
class MultiProbe(TracingMethod):
    name = "multi_probe"
    Params = Params
    ratio_where_valid = True
    knob = Knob("steps_per_texel", (0.25, 0.5, 1.0, 2.0))

    def spec(self) -> ProbeSpec:
        return probe_spec(self.params)

    def views_needed(self) -> Views:
        return Views(probes=(self.spec(),))

    def _choose(self, B, P, pt: V3, untried: list):
        """Index of the nearest untried probe that sees ``pt`` (−1: none), and the lookups it took (N)."""
        best, best_d = pt.x * 0.0 - 1.0, pt.x * 0.0 + 3e38
        for i in range(P.n):
            k = pt.x * 0.0 + float(i)
            v = pt - P.centre(k)
            dist = B.length(v)
            ok = untried[i] & (dist <= P.distance(k, v) * 1.0001 + 1e-6) & (dist < best_d)
            best, best_d = B.select(ok, k, best), B.select(ok, dist, best_d)
        return best

    def _choose_where(self, B, P, mask, pt: V3, untried: list):
        """:meth:`_choose` on the lanes of ``mask``, −1 on the others (a branch: a GPU warp with none of them reads
        nothing)."""

        def not_chosen(x, y, z, *u):
            return (x * 0.0 - 1.0,)

        return B.branch(
            mask,
            (pt.x, pt.y, pt.z, *untried),
            lambda x, y, z, *u: (self._choose(B, P, V3(x, y, z), list(u)),),
            not_chosen,
        )[0]

    def _resolve(self, B, P, g, br, active, xs: V3, R: V3, a, k):
        """The round's secant steps on its bracket ``br`` and the crossing's class (module docstring, 2.) on the
        lanes of ``active`` (a branch): (the bracket's t_lo, the crossing l (from c_k), cross, ok: HIT where ok, else
        UNKNOWN where it crossed); elsewhere t_lo, placeholders and False."""
        p, res = self.params, P.res
        zero = a * 0.0  # (a > 0 and finite)

        def resolve(t_lo, g_lo, t_hi, g_hi, found):
            br = refine(B, g, Bracket(t_lo, g_lo, t_hi, g_hi, found), p.secant_steps, rising=True)
            t = secant_point(br)
            t_ok = B.isfinite(t)
            t = B.select(t_ok, t, zero)
            l = _finite(B, (xs * (1.0 - t) + R * (a * t)) / B.maximum(1.0 - t, 1e-7))  # crossing, from c_k
            r = B.length(l)
            tol = p.thickness + (r * (p.slack / res) if res else zero)
            cross = br.found & t_ok
            w = l / B.maximum(r, 1e-9)  # texels either side along the arc
            tan = R - w * w.dot(R)
            tan = tan * ((2.0 / max(res, 1)) / B.maximum(B.length(tan), 1e-9))
            d_lo, d_at, d_hi = P.nearest(k, w - tan), P.nearest(k, l), P.nearest(k, w + tan)
            step = (d_lo - d_hi > tol) & (B.abs(d_lo + d_hi - 2.0 * d_at) > 0.5 * (d_lo - d_hi))
            ok = cross & ~step & (B.abs(r - d_at) <= tol + 0.25 * B.abs(d_hi - d_lo))
            return br.t_lo, l.x, l.y, l.z, cross, ok

        def not_resolved(t_lo, g_lo, t_hi, g_hi, f):
            never = f & ~f
            return t_lo, t_lo, t_lo, t_lo, never, never

        return B.branch(active, tuple(br), resolve, not_resolved)

    def _probes(self, env):
        return env.need_probes(self.name, self.spec()) or _Single(env)

    def sees_origin(self, B: Backend, env: Captured, x: V3):
        """Rays whose origin some probe sees (N more lookups, not counted)."""
        P = self._probes(env)
        never = B.isfinite(x.x) & ~B.isfinite(x.x)
        return self._choose(B, P, _finite(B, x), [~never] * P.n) >= 0.0

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        p = self.params
        P = self._probes(env)
        N, res = P.n, P.res
        n = march_steps(res, p)
        zero = x.x * 0.0
        never = B.isfinite(zero) & ~B.isfinite(zero)  # all False
        # ------------------------------------------------------------- the first probe: nearest that sees x
        untried = [~never for _ in range(N)]
        k = self._choose(B, P, x, untried)
        k = B.select(k >= 0.0, k, zero)  # no probe sees x: probe 0 (trace's origin check may drop the ray)
        active = B.isfinite(B.length(R)) & B.isfinite(B.length(x))
        R, x = _finite(B, R), _finite(B, x)  # dropped rays (NaN) stay inactive; lookups see no NaN
        untried = [u & (k != float(i)) for i, u in enumerate(untried)]
        spent = zero + float(N)
        d0 = zero  # ray parameter where the current segment starts
        found, have_first = never, never
        hit_l, hit_k, first_l, first_k, table = x, zero, x, zero, None  # table: the arc's, for every round
        for _ in range(N):
            if not B.numpy(active).any():
                break
            # --------------------------------------------------------- march the segment on probe k
            c = P.centre(k)
            xs = x + R * d0 - c
            a = B.maximum(B.length(xs), 1e-6)
            kk = k

            def g(t, xs=xs, a=a, kk=kk):
                pt = _finite(B, xs * (1.0 - t) + R * (a * t))  # a secant point may be NaN (g_hi = g_lo)
                return B.length(pt) - (1.0 - t) * P.distance(kk, pt)

            g0 = g(zero)
            skip = _skip(B, P, xs, R, a, n, kk) if p.hierarchical else None
            smp = arc_samples(B, xs.dot(R) / a, n, table)
            br = first_crossing(
                B,
                g,
                zero,
                g0,
                smp,
                n,
                t_max=1.0,
                default=(zero, g0, zero + 1.0, a),
                skip=skip,
                active=active,  # a ray resolved in an earlier round marches no more
            )
            marched = zero + float(n) if skip is None else skip.lookups  # the texel march: all n samples
            table = smp.table

            # a ray resolved in an earlier round: no secant step nor texel read (a GPU warp of such rays skips it)
            t_lo, lx, ly, lz, cross, ok = self._resolve(B, P, g, br, active, xs, R, a, k)
            l = V3(lx, ly, lz)
            hit = active & ok
            unknown = active & cross & ~ok
            spent = spent + B.select(active, marched + float(p.secant_steps + 4), zero)
            found = found | hit
            hit_l, hit_k = _sel(B, hit, l + c, hit_l), B.select(hit, k, hit_k)
            first = unknown & ~have_first
            first_l, first_k = _sel(B, first, l + c, first_l), B.select(first, k, first_k)
            have_first = have_first | first
            # --------------------------------------------------------- UNKNOWN: on in the next probe
            d0 = B.select(unknown, d0 + a * t_lo / B.maximum(1.0 - t_lo, 1e-7), d0)
            k_next = self._choose_where(B, P, unknown, x + R * d0, untried)
            spent = spent + B.select(unknown, zero + float(N), zero)
            active = unknown & (k_next >= 0.0)
            k = B.select(active, k_next, k)
            untried = [u & ~(active & (k == float(i))) for i, u in enumerate(untried)]
            B.eval(d0, k, active, found, spent, hit_l.x, hit_l.y, hit_l.z, hit_k)
        # ------------------------------------------------------------- the shown point, from the probe that saw it
        use_first = ~found & have_first
        valid = found | use_first
        kf = B.select(use_first, first_k, hit_k)
        v = _sel(B, use_first, first_l, hit_l) - P.centre(kf)
        v = _sel(B, valid, v, R)  # finite everywhere (numpy gathers every ray)
        ch = P.lookup(kf, v)
        shown = P.centre(kf) + B.normalize(v) * ch[-1]
        return Found(shown, shown, V3(*ch[:3]), B.length(v) / ch[-1], valid, spent + 1.0)

    def lookups_per_ray(self, res: int | None = None) -> float:
        # N rounds (module docstring), N = probe 0 + the grid's cells or the points (probes inside geometry dropped)
        p = self.params
        N = 1 + (len(p.points) if p.points is not None else int(np.prod(p.grid)))
        return N + N * (march_bound(res, p) + p.secant_steps + 4 + N) + 1
