"""Distance-field tracing (sphere tracing, Hart 1996, through a global signed distance field, as Unreal Engine 5's
Lumen traces reflections without ray-tracing hardware): the ray marches through a 3D grid of signed distances of
the environment; the hit is shaded from what a radiance cache holds.

The view searched is ``Captured.sdfs[spec]`` (:class:`study.impostor.sdf.SdfGrid`, built from the environment's own
triangles, ``spec`` = :class:`~study.impostor.views.SdfSpec` of ``res`` and ``band``); on a bare impostor without it,
the field of the room box (``Captured.room``) stands in (the bench: the cost of a fetch does not depend on the
values).

Per ray x + R t (relative to o), φ the trilinear signed distance (one 3D fetch):

1. **sphere trace**: t₀ = 0; at each step φ(x + R t); where φ ≤ 0 the surface was crossed between the previous
   sample and this one (a bracket, the march ends); else t ← t + max(φ, ``min_step``·h) (h the voxel size; φ is a
   lower bound of the distance outside the narrow band and exact on planes inside it, the floor keeps a ray grazing
   a surface moving and makes it cross within ``min_step`` voxels). The march also ends where the point leaves
   the grid's cube (no hit) or after ``max_steps`` fetches (no hit: the budget ran out).
2. **refine**: ``refine_steps`` Illinois secant steps on the bracket (:func:`study.methods.search.refine`) → t*,
   the hit p = x + R t* (the shown point, on the ray).
3. **shade**: with ``shading = "impostor"`` the impostor's radiance in the direction of p seen from o (one lookup;
   where p is hidden from o that is the occluder's radiance: the cache's error, not the field's);
   ``"probes"`` the radiance of the nearest probe that sees p (:class:`study.impostor.probes.ProbeSet` of
   ``grid``, as ``multi_probe`` captures it; N lookups to choose, one to read); ``"exact"`` the radiance Mitsuba
   path traces along R from 2 voxels before the hit (``Captured.shade``, the scene without the object, as
   ``truth_at_hit`` but with a seed of its own; counted as one lookup): what a perfect radiance cache gives at
   that point, so the error left is the field's geometry alone, and sdf's error less this variant's is the
   cache's. Not on the bench (no Mitsuba there: the impostor shades instead).

Cost per ray (``Trace.lookups``): φ at the origin + the fetches of the march actually taken (a GPU thread stops at
its bracket) + 1 + ``refine_steps`` on rays with a bracket (the bracket's near end re-read, the secant steps) + the
shading lookups; :meth:`SDF.lookups_per_ray` bounds it with ``max_steps``. Every fetch of φ is a 3D (trilinear)
fetch, counted as a lookup; :meth:`SDF.volume_lookups` says how many of the bound they are, and the bench's floor
prices them at the measured 3D fetch rate (:mod:`study.bench.floors`).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor.sdf import SdfGrid, room_field
from study.impostor.views import Captured, ProbeSpec, SdfSpec, Views
from study.methods.base import Found, Knob, TracingMethod, register
from study.methods.search import Bracket, refine, secant_point


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    # 128 by default (8 MiB of float32 nodes): at 64³ fig5's first case showed 15.7 % of the rays hidden from o at
    # a wrong point, at 128³ 3.1 % (≤ 5 %), at 256³ 2.3 % (64 MiB) for +0.4 lookups a ray
    res: Annotated[int, Field(ge=16, le=512, description="grid nodes per axis of the distance field")] = 128
    band: Annotated[float, Field(ge=1, le=32, description="narrow band of exact distances, voxels")] = 4.0
    max_steps: Annotated[int, Field(ge=1, le=4096, description="sphere-tracing step budget (3D fetches)")] = (
        96
    )
    min_step: Annotated[float, Field(gt=0, le=4, description="smallest step, voxels")] = 0.25
    refine_steps: Annotated[int, Field(ge=0, le=64, description="Illinois secant steps on the bracket")] = 4
    shading: Literal["impostor", "probes", "exact"] = Field(
        "impostor",
        description="radiance of the hit: the impostor from o, the nearest probe that sees it, or exact",
    )
    grid: tuple[
        Annotated[int, Field(ge=1, le=8)],
        Annotated[int, Field(ge=1, le=8)],
        Annotated[int, Field(ge=1, le=8)],
    ] = Field((2, 2, 2), description="with shading = 'probes': the probe grid (multi_probe's)")


def _sel(B, m, a: V3, b: V3) -> V3:
    return V3(B.select(m, a.x, b.x), B.select(m, a.y, b.y), B.select(m, a.z, b.z))


@register
class SDF(TracingMethod):
    name = "sdf"
    Params = Params
    ratio_where_valid = True
    knob = Knob("res", (32, 64, 128))

    def spec(self) -> SdfSpec:
        return SdfSpec(res=self.params.res, band=self.params.band)

    def probe_spec(self) -> ProbeSpec:
        return ProbeSpec(grid=tuple(self.params.grid))

    def views_needed(self) -> Views:
        probes = (self.probe_spec(),) if self.params.shading == "probes" else ()
        return Views(sdfs=(self.spec(),), probes=probes, shade=self.params.shading == "exact")

    def field(self, env) -> SdfGrid:
        """The distance field searched: the captured one, or the room box's on a fallback Captured."""
        f = env.need_sdf(self.name, self.spec())
        return f if f is not None else room_field(env, self.spec())

    # ---------------------------------------------------------------------------------------------- the search
    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        p = self.params
        phi = self.field(env)
        h = phi.h
        zero = x.x * 0.0
        never = B.isfinite(zero) & ~B.isfinite(zero)
        lo = [float(c) for c in phi.shift]
        hi = [c + phi.extent for c in lo]
        active0 = B.isfinite(B.length(R)) & B.isfinite(B.length(x))
        x = V3(*(B.select(active0, c, 0.0) for c in (x.x, x.y, x.z)))
        R = V3(*(B.select(active0, c, 1.0) for c in (R.x, R.y, R.z)))

        def inside(q: V3):
            return (
                (q.x >= lo[0])
                & (q.x <= hi[0])
                & (q.y >= lo[1])
                & (q.y <= hi[1])
                & (q.z >= lo[2])
                & (q.z <= hi[2])
            )

        # ------------------------------------------------------------- sphere trace to the first bracket
        def step(t, t_prev, d_prev, found, stop, spent):
            q = x + R * t
            run = ~found & ~stop & inside(q)
            stop = stop | (~found & ~inside(q))
            d = phi.distance(q)
            spent = spent + B.select(run, zero + 1.0, zero)
            cross = run & (d <= 0.0)
            found = found | cross
            move = run & ~cross
            t_prev = B.select(move, t, t_prev)
            d_prev = B.select(run, d, d_prev)  # on a crossing: g at the bracket's far end
            t = B.select(move, t + B.maximum(d, p.min_step * h), t)
            return t, t_prev, d_prev, found, stop, spent

        d0 = phi.distance(x)  # φ at the origin: the bracket's near end if the first step crosses
        state = (zero, zero, d0, never, ~active0, zero + 1.0)  # d0 counted
        t, t_prev, d_hi, found, _, spent = B.loop(p.max_steps, state, step)
        # g at t_prev: φ there was the step before the crossing; re-read once (counted with the refinement)
        g_lo = phi.distance(x + R * t_prev)
        br = Bracket(t_prev, g_lo, t, d_hi, found)
        br = refine(B, lambda s: phi.distance(x + R * s), br, p.refine_steps)
        ts = secant_point(br)
        ts = B.select(B.isfinite(ts), ts, t)
        spent = spent + B.select(found, zero + float(p.refine_steps + 1), zero)
        hit = x + R * ts
        hit = _sel(B, found, hit, R)  # finite everywhere (numpy gathers every ray)
        # ------------------------------------------------------------- shade the hit
        shade = env.need_shade(self.name) if p.shading == "exact" else None
        if p.shading == "probes":
            rgb, ratio, extra = self._probe_shade(B, env, hit, 2.0 * h)
        elif shade is not None:
            rgb, ratio, extra = self._exact_shade(B, env, shade, x, R, ts, found, 2.0 * h)
        else:
            ch = env.lookup(hit)
            rgb, ratio, extra = ch[:3], B.length(hit) / ch[-1], 1.0
        return Found(hit, hit, V3(*rgb), ratio, found, spent + extra)

    def _probe_shade(self, B, env, hit: V3, tol: float):
        """Radiance of the nearest probe that sees ``hit`` within ``tol`` metres (probe 0 where none does), the
        ratio |hit − c|/|·|' there, and the lookups (N + 1)."""
        P = env.need_probes(self.name, self.probe_spec())
        if P is None:
            ch = env.lookup(hit)
            return ch[:3], B.length(hit) / ch[-1], 1.0
        zero = hit.x * 0.0
        best, best_d = zero, zero + 3e38
        for i in range(P.n):
            k = zero + float(i)
            v = hit - P.centre(k)
            dist = B.length(v)
            ok = (dist <= P.distance(k, v) + tol) & (dist < best_d)
            best, best_d = B.select(ok, k, best), B.select(ok, dist, best_d)
        v = hit - P.centre(best)
        ch = P.lookup(best, v)
        return ch[:3], B.length(v) / ch[-1], float(P.n + 1)

    def _exact_shade(self, B, env, shade, x, R, ts, found, back: float):
        """Radiance arriving along R at the point ``back`` metres before the hit (not before x), path traced by
        ``shade``: the hit's own radiance where the field put it on the right surface, another surface's where it
        did not (a geometric error, and nothing else). The ratio from one impostor lookup (a diagnostic); the
        lookups: 1 (the read of a radiance cache it stands for)."""
        start = x + R * B.maximum(ts - back, 0.0)
        ok = B.numpy(found).astype(bool)
        pts = B.to_numpy(start).astype(float) + env.origin()
        rad = np.full((len(ok), 3), np.nan, np.float32)
        if ok.any():
            rad[ok] = shade(pts[ok], B.to_numpy(R)[ok].astype(float))
        hit = x + R * ts
        safe = _sel(B, found, hit, R)
        ratio = B.length(safe) / env.distance(safe)
        return [B.array(rad[:, i]) for i in range(3)], ratio, 1.0

    def lookups_per_ray(self, res: int | None = None) -> float:
        # the 3D fetches (volume_lookups) and the shading lookups: the impostor's one, or N + 1 probe lookups
        p = self.params
        shade = 1 + (1 + int(np.prod(p.grid)) if p.shading == "probes" else 0)
        return self.volume_lookups(res) + shade

    def volume_lookups(self, res: int | None = None) -> float:
        # φ at the origin, the march, the bracket's near end re-read, the secant steps
        p = self.params
        return 1 + p.max_steps + 1 + p.refine_steps
