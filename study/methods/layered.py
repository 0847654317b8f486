"""Layered distance maps (GPU Gems 3 ch. 17; Hakura and Snyder 2001): every depth layer searched, nearest clean
hit kept.

Layers come from ``env.info["layers"]`` (:mod:`study.impostor.layers`: layer k holds the (k+1)-th surface seen from the
reference point o, channels R, G, B, jump, distance); on a bare impostor without layers, the impostor itself is
the only layer (no jump channel, so no hit is ever rejected as skin).

Search (per layer, all layers on the same samples): the linear search of :mod:`study.methods.linear_secant` (the
t = d/(d + a) parameterization, n = max(n_max (1 − x̂·R)/2, n_min) steps along the arc) on
g_k(t) = |p(t)| − (1 − t) |p(t)'|_k, recording the first TWO sign changes of each layer in either direction
(under → over: the ray passes a surface that faces o; over → under: a surface that faces away from o, such as a
column top seen from below, which is how a layer behind the first holds it); each is refined by ``iterations``
Illinois secant steps (both phases from the search core :mod:`study.methods.search`). One lookup at each refined
point reads q = |l|/|l'|_k, the layer's relative depth jump and the radiance. A crossing is *clean* where
|q − 1| ≤ ``tolerance`` and the jump is below ``max_jump``; a crossing on a depth discontinuity is the "skin" that
bilinear interpolation stretches from a silhouette to what lies behind it, not a surface.

Why not the paper's false position on each layer: on the layer that holds a column top (seen from below), a ray
coming down onto the top first crosses the skin along the top's silhouette edge and then the top itself; false
position converges on the skin (the first root of its first bracket) and never reaches the top (see
tests/test_methods_layered.py). Recording two crossings per layer lets the skin be rejected and the top kept.

Kept: the nearest clean crossing over all layers; where none is clean, the nearest crossing with |q − 1| ≤
``tolerance``; where none is, the first crossing of the first layer. valid: some crossing was found. The shown
point and radiance come from the layer the hit was kept from (``trace`` is overridden for that).
"""
from __future__ import annotations

from functools import partial
from typing import Annotated

from pydantic import Field

from study.backend import V3
from study.methods.base import Knob, Localization, Method, Trace, register
from study.methods.linear_secant import LinearSearchParams
from study.methods.search import refine, secant_point, sign_changes


class Params(LinearSearchParams):                                # + linear_steps, min_linear_steps
    layers: Annotated[int, Field(ge=1, le=16)] = 3               # depth layers searched
    iterations: Annotated[int, Field(ge=0, le=1000)] = 10        # secant steps per crossing
    tolerance: Annotated[float, Field(gt=0)] = 0.01              # |q − 1| of a converged crossing
    max_jump: Annotated[float, Field(gt=0)] = 0.1                # relative depth jump above which it is skin


@register
class Layered(Method):
    name = "layered"
    Params = Params
    knob = Knob("linear_steps", (15, 30, 60, 120))    # a finer linear search steps over fewer thin crossings

    def layers_needed(self) -> int:
        return self.params.layers

    def _search(self, B, env, x, R):
        """Returns (l, valid, [r, g, b], distance) of the kept hit."""
        p = self.params
        maps = list(env.info.get("layers") or [env])[:p.layers]
        # ------------------------------------------------------------- parameterization and step count
        xl = B.length(x)
        a = B.maximum(xl, 1e-6)                        # a = |x|
        cos = x.dot(R) / a                             # x̂·R
        n = B.maximum(p.linear_steps * (1.0 - cos) * 0.5, float(p.min_linear_steps))
        dt = 1.0 / B.minimum(n, float(p.linear_steps))
        zero = xl * 0.0

        def point(t):                                  # p(t) = (1 − t) x + t a R
            return x * (1.0 - t) + R * (a * t)

        def g(m, t):
            pt = point(t)
            return B.length(pt) - (1.0 - t) * m.distance(pt)

        # ------------------------------------------------------------- linear search: first two sign changes
        # per layer, two brackets (a harmless dummy bracket until found, so that refining it stays finite)
        dummy = (zero, zero - 1.0, zero + 1.0, zero + 1.0)
        cross = sign_changes(B, lambda t: [g(m, t) for m in maps], zero, [g(m, zero) for m in maps], dt,
                             p.linear_steps, count=2, t_max=1.0, default=dummy)

        # ------------------------------------------------------------- secant refinement, test, nearest kept
        big = 1e30
        best = None
        for i, m in enumerate(maps):
            for j, br in enumerate(cross[i]):
                br = refine(B, partial(g, m), br, p.iterations)      # Illinois secant steps
                t, found = secant_point(br), br.found
                l = point(t) / B.maximum(1.0 - t, 1e-7)          # x + R d(t)
                ch = m.lookup(l)
                dist = ch[-1]
                jump = ch[3] if m.channels == 5 else zero
                conv = found & B.isfinite(t) & (B.abs(B.length(l) / dist - 1.0) <= p.tolerance)
                clean = conv & (jump < p.max_jump)
                # rank: clean crossings by t, then converged ones, then the first layer's first crossing
                key = B.select(clean, t, B.select(conv, t + 10.0, zero + (100.0 if i == j == 0 else big)))
                key = B.select(found, key, zero + big * 2)
                cand = (l.x, l.y, l.z, ch[0], ch[1], ch[2], dist, key)
                if best is None:
                    best = cand
                else:
                    take = cand[-1] < best[-1]
                    best = tuple(B.select(take, c, b) for c, b in zip(cand, best))
        lx, ly, lz, r, gg, b, dist, key = best
        return V3(lx, ly, lz), key < big, [r, gg, b], dist

    def localize(self, B, env, x, R):
        l, valid, _, _ = self._search(B, env, x, R)
        return Localization(l=l, valid=valid)

    def trace(self, B, env, x, R, *, check_origin: bool = True):
        """As :meth:`Method.trace` (same origin check), reading the kept layer's distance and radiance."""
        l, valid, rgb, dist = self._search(B, env, x, R)
        valid = valid & B.isfinite(B.length(R))
        if check_origin:
            valid = valid & (B.length(x) <= env.distance(x) * 1.0001 + 1e-6)   # x is an undershoot
        lhat = B.normalize(l)
        nan = float("nan")
        shown = V3(*(B.select(valid, c * dist, nan) for c in (lhat.x, lhat.y, lhat.z)))
        rad = V3(*(B.select(valid, c, nan) for c in rgb))
        return Trace(l, shown, rad, B.length(l) / dist, valid)

    def lookups_per_ray(self) -> int:
        # per layer: g(0), n_max linear steps, two crossings × (secant steps + the final lookup that gives the
        # test, the jump and the shown point's distance and radiance)
        p = self.params
        return p.layers * (1 + p.linear_steps + 2 * (p.iterations + 1))
