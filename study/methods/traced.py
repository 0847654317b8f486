"""The exact query as a method (``traced``: tracing the rays, as a hardware ray tracer would): each ray is cast
against the environment's own triangles by the case's exact tracer — Embree on the CPU, Mitsuba's OptiX
``ray_intersect_preliminary`` on CUDA (:mod:`study.reference.tracer`) — and its hit shaded exactly.

What it is for: the row that answers "would tracing the rays be cheaper?" on the same rays and the same columns as
the stand-ins. Its hit is the exact hit (zero wrong hits in the outcome columns, up to float32 rounding of the ray),
its radiance is the radiance arriving along the ray (``Captured.shade``,
:func:`study.measure.inputs.exact_shading`): on the case's exact rays ``truth_at_hit``'s own value (the same rays,
the same samples), so on a mirror object its image is the truth's up to float rounding and it never ranks below a
stand-in on a column against the truth for path-tracing noise of its own; on other rays (a glass object's rays
through its distance map, which are not the exact ones; a rough object, whose truth is its lobe's average) path
traced by Mitsuba in the scene without the object with a seed of its own; where a stand-in then scores better on a
column of the method, the run's notes say so for this row (:mod:`study.measure.exact_rows`) and no ranking holds
it. A ray that leaves an open environment
is shown at infinity along its direction (``cubemap.FAR``) with the radiance found along it.

Columns: it reads none of the reference point's views (:attr:`reads_views` False), so its rows leave out (NaN) the
columns measured against the cube map at the exact hit: every ``*_oracle`` column and the error split ``dec_*``.
With its image the truth's, img − oracle is truth − oracle, the map's own error, not the method's (the truth's row
leaves the split out for the same reason).

Inputs: the case hands over the exact tracer's first hits (``Captured.hits``, asked for with ``Views(hits=True)``)
and exact shading; the method reads no image-based view. Rays are traced from their own origins whatever the
reference point sees (no origin check: a tracer does not need o to see x). On glass objects the rays are the
methods' rays (through the object's own distance map), so where those differ from the exactly refracted rays the
hit differs too: the exact query on the same rays, not the exact image.

Cost: one lookup per ray is counted (the read of the hit's radiance); the ray query itself is no cube-map lookup.
``study bench`` does not time the method's Python path (a host round trip through numpy here): its row there takes
the time the bench measures for what a renderer pays to trace and shade the ray on Mitsuba's device of the
backend (Embree's query for numpy): the full ``ray_intersect`` (the SurfaceInteraction a material needs), the
material evaluated towards the point light and the shadow ray to it (:data:`ExactQuery.shades_hit`, path
``shaded``), as every stand-in's price holds its radiance fetch; the bare query (:data:`ExactQuery.bench_query`,
the cheapest that returns the hit) is stated beside it (``query_ms_per_frame``), and ``study pareto`` says both.

On a bare impostor (no scene to trace: the analytic tests) the room box stands in for the scene
(``Captured.room``, else the box fitted to the impostor as ``proxy_box`` fits it), intersected exactly, and the
impostor is read towards the hit.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from study.backend import V3, Backend
from study.impostor.cubemap import FAR
from study.impostor.views import Captured, Views
from study.methods.base import Found, TracingMethod, register
from study.methods.proxy_box import room_box


@register
class ExactQuery(TracingMethod):
    name = "traced"
    ratio_where_valid = True
    #: The exact query whose measured time ``study bench`` gives this method's rows (the hit distance and the
    #: primitive: what a hit point needs).
    bench_query: ClassVar[str] = "ray_intersect_preliminary"
    #: Priced with the shading a renderer does at the hit (``study bench``: the material towards the point light
    #: and the shadow ray, :data:`study.bench.timing.SHADING`), as each stand-in's price holds its radiance fetch.
    shades_hit: ClassVar[bool] = True
    #: It reads no cube map: its rows leave out the oracle's and the split's columns (module docstring).
    reads_views: ClassVar[bool] = False

    def views_needed(self) -> Views:
        return Views(hits=True, shade=True)

    def lookups_per_ray(self, res: int | None = None) -> float:
        return 1  # the hit's radiance read; the ray query is no cube-map lookup

    def sees_origin(self, B: Backend, env: Captured, x: V3):
        """Every finite origin: a tracer needs no view of x (on a bare impostor: the base's check)."""
        if env.hits is None:
            return super().sees_origin(B, env, x)
        return B.isfinite(B.length(x))

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        if env.need_hits(self.name) is None:
            return self._box(B, env, x, R)
        shade = env.need_shade(self.name)
        return self._exact(B, env, x, R, lambda xw, d, escapes: shade(xw, d))

    def _exact(self, B: Backend, env: Captured, x: V3, R: V3, radiance) -> Found:
        """The exact hits of the rays (escaping ones at infinity along them) with ``radiance(xw, d, escapes)``:
        (n, 3) for the finite rays' world origins, directions and which of them leave the scene."""
        hits, o = env.need_hits(self.name), env.origin()
        xw = B.to_numpy(x).astype(np.float64) + o
        d = B.to_numpy(R).astype(np.float64)
        ok = np.isfinite(xw).all(-1) & np.isfinite(d).all(-1)
        shown = np.full_like(xw, np.nan)
        rad = np.full_like(xw, np.nan)
        if ok.any():
            pts = np.asarray(hits(xw[ok], d[ok]), np.float64)
            escapes = ~np.isfinite(pts).all(
                -1
            )  # the ray leaves the scene: "no surface", at infinity along it
            pts[escapes] = xw[ok][escapes] + d[ok][escapes] * FAR
            shown[ok] = pts - o
            rad[ok] = radiance(xw[ok], d[ok], escapes)
        valid = B.array(ok.astype(np.float32)) > 0.5
        one = x.x * 0.0 + 1.0
        return Found(B.vec(shown), B.vec(shown), B.vec(rad), one, valid, one)

    def _box(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        """The fallback: the exact hit with the room box, its radiance read from the impostor towards it."""
        lo, hi = room_box(B, env)
        t = None
        for xi, Ri, a, b in ((x.x, R.x, lo[0], hi[0]), (x.y, R.y, lo[1], hi[1]), (x.z, R.z, lo[2], hi[2])):
            plane = B.select(Ri > 0.0, xi * 0.0 + float(b), xi * 0.0 + float(a))
            ti = B.select(Ri == 0.0, xi * 0.0 + np.float32(np.inf), (plane - xi) / Ri)
            t = ti if t is None else B.minimum(t, ti)
        valid = B.isfinite(t) & (t >= 0.0)
        t = B.select(valid, t, 0.0)
        hit = x + R * t
        safe = V3(*(B.select(valid, c, d) for c, d in zip((hit.x, hit.y, hit.z), (R.x, R.y, R.z))))
        r, g, b, dist = env.lookup(safe)
        return Found(hit, hit, V3(r, g, b), B.length(safe) / dist, valid, x.x * 0.0 + 1.0)
