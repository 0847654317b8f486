"""Blending several parallax-corrected probes (Lagarde and Zanuttini, "Local Image-based Lighting With
Parallax-corrected Cubemap", SIGGRAPH 2012; the reflection probes Unity and Unreal ship): each probe's cube map is
looked up box- or sphere-projected, and a shading point blends the probes whose influence volumes hold it.

Probes: the set ``Captured.probes[spec]`` (:class:`study.impostor.probes.ProbeSet`) placed by the rule
``multi_probe`` uses (``grid`` / ``points`` / ``clearance``, the same defaults, so the two methods share one capture:
the centres of a grid of equal cells in the environment's bounds, less those inside geometry or nearer than
``clearance`` to a surface). Probe 0, the reference point's impostor, is the global probe: it is used only where no
other probe's influence reaches. On a bare impostor without probes, probe 0 alone (the method is then ``proxy_box``,
or a sphere-projected lookup from o).

Influence of probe k (centre c_k, half-size h: half a grid cell, ``Captured.room`` divided by ``grid``; ``radius``
on every axis for ``points``): the normalized distance NDF_k of the shading point x (the ray's origin) is 0 inside
the inner volume and rises to 1 at the outer one, ``blend`` metres inside and outside the cell: box
(``influence="box"``) NDF = max over axes of clamp((|x − c_k|ᵢ − (hᵢ − b)) / 2b, 0, 1); sphere NDF = clamp((|x − c_k|
− (|h| − b)) / 2b, 0, 1), |h| the half diagonal (b = 0: a step at the boundary). Probe k influences x where NDF_k < 1.

Weights (Lagarde 2012): n influencing probes; n = 1: that probe alone; n ≥ 2: w_k = (1 − NDF_k/ΣNDF)/(n − 1) ·
(1 − NDF_k)/Σ(1 − NDF), normalized to sum 1 (equal where ΣNDF = 0: x inside several inner volumes); n = 0: the
global probe. A probe weighs 0 at its outer boundary and outweighs the others inside its inner volume.

Projection (``projection``): ``"box"``, the ray's exit from the room box (``Captured.room``, as ``proxy_box``) p =
x + R t*, looked up from c_k in direction p − c_k; ``"sphere"``, p the ray's far root on the sphere around c_k
whose radius is the mean distance from c_k to the room box (as ``proxy_sphere`` fits its sphere about o), a probe
whose sphere the ray misses weighing 0. Probe k's answer is the point it holds in that direction, c_k + (p −
c_k)^·|p − c_k|'_k, and its radiance.

Shown point (the outcome classes): the answer of the probe of largest weight; radiance Σ w_k·(probe k's).
**Ghosting** (the column ``ghost_fraction``, declared here and filled through ``Found.flags``; no outcome class):
the rays whose blend gives ≥ :data:`GHOST_WEIGHT` to a probe whose answer lies farther than max(1 cm, one texel of
that probe at its answer) from the shown point, so the image mixes two surfaces. Cost per ray: one lookup per probe
of weight > 0 (the weights are analytic); :meth:`ProbeBlend.lookups_per_ray` bounds it with every probe.
:func:`blend_weights_ref` is the weights' slow twin (one point, plain floats).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from study import columns
from study.backend import V3, Backend
from study.impostor import analytic
from study.impostor.views import Captured, ProbeSpec, Views
from study.methods.base import Found, Knob, TracingMethod, register
from study.methods.multi_probe import ProbeGridParams, probe_spec
from study.methods.proxy_box import room_box
from study.methods.proxy_sphere import fibonacci_directions

#: A probe with at least this weight whose answer differs from the shown point makes the ray a ghost.
GHOST_WEIGHT = 0.1
GHOST = "ghost_fraction"

if columns.declared(GHOST) is None:
    columns.declare(
        columns.TableColumn(
            GHOST,
            "fraction",
            True,
            note="probe_blend: rays whose blend weighs (≥ 0.1) a probe that shows another point (ghosting)",
        )
    )


class Params(ProbeGridParams):  # the probes of multi_probe's grid, then how they are blended
    projection: Literal["box", "sphere"] = Field(
        "box", description="parallax correction of each probe's lookup"
    )
    influence: Literal["box", "sphere"] = Field("box", description="shape of each probe's influence volume")
    blend: Annotated[
        float, Field(ge=0, le=10, description="half-width of the blend region at a cell's boundary, metres")
    ] = 0.25
    radius: Annotated[float, Field(gt=0, le=100)] | None = Field(
        None, description="influence half-size of ``points`` probes, metres (default 1)"
    )


def _clamp01(B, a):
    return B.minimum(B.maximum(a, 0.0), 1.0)


def _ndf(B, a, inner: float, b: float):
    """Normalized distance from ``a`` (distances from the centre) between inner − … : 0 inside, 1 at inner + 2b."""
    if b <= 0:
        return B.select(a > inner, a * 0.0 + 1.0, a * 0.0)
    return _clamp01(B, (a - inner) / (2.0 * b))


def blend_weights(B, ndf: list):
    """Lagarde's weights of the probes of normalized distances ``ndf`` (per ray; ≥ 1: no influence), and the
    global probe's weight (1 where none influences)."""
    zero = ndf[0] * 0.0 if ndf else None
    if not ndf:
        return [], None
    inside = [d < 1.0 for d in ndf]
    n = sum(B.select(m, zero + 1.0, zero) for m in inside)
    s = sum(B.select(m, d, zero) for m, d in zip(inside, ndf))
    inv = sum(B.select(m, 1.0 - d, zero) for m, d in zip(inside, ndf))
    s_, inv_ = B.select(s > 0.0, s, zero + 1.0), B.select(inv > 0.0, inv, zero + 1.0)
    w = []
    for m, d in zip(inside, ndf):
        d = B.select(m, d, zero)
        multi = (1.0 - d / s_) / B.maximum(n - 1.0, 1.0) * (1.0 - d) / inv_
        wk = B.select((n >= 2.0) & (s > 0.0), multi, zero + 1.0)
        w.append(B.select(m, wk, zero))
    total = sum(w)
    w = [B.select(total > 0.0, a / B.select(total > 0.0, total, zero + 1.0), zero) for a in w]
    return w, B.select(n == 0.0, zero + 1.0, zero)


def blend_weights_ref(ndf: list[float]) -> list[float]:
    """Slow twin of :func:`blend_weights` at one point: Lagarde's loop in plain floats (global probe last)."""
    idx = [k for k, d in enumerate(ndf) if d < 1.0]
    out = [0.0] * (len(ndf) + 1)
    if not idx:
        out[-1] = 1.0
        return out
    if len(idx) == 1:
        out[idx[0]] = 1.0
        return out
    s = sum(ndf[k] for k in idx)
    inv = sum(1.0 - ndf[k] for k in idx)
    for k in idx:
        out[k] = (1.0 - ndf[k] / s) / (len(idx) - 1) * (1.0 - ndf[k]) / inv if s > 0 else 1.0
    total = sum(out)
    return [v / total for v in out]


class _Only:
    """The impostor as the only probe (a bare impostor without ``Captured.probes``)."""

    def __init__(self, env):
        self.env, self.n, self.res = env, 1, getattr(env, "res", 0)
        self.centres = np.zeros((1, 3))

    def lookup(self, k, v):
        return self.env.lookup(v)


@register
class ProbeBlend(TracingMethod):
    name = "probe_blend"
    Params = Params
    ratio_where_valid = True
    knob = Knob("blend", (0.0, 0.1, 0.25, 0.5))

    def spec(self) -> ProbeSpec:
        return probe_spec(self.params)  # the probes of multi_probe's grid: one capture serves both

    def views_needed(self) -> Views:
        return Views(probes=(self.spec(),))

    def _half(self, lo, hi) -> np.ndarray:
        p = self.params
        if p.points is not None:
            return np.full(3, p.radius if p.radius is not None else 1.0)
        return (hi - lo) / np.asarray(p.grid, float) / 2.0

    def _project(self, B, x, R, c: np.ndarray, lo, hi, box_t):
        """The proxy point p of the rays for a probe at c (relative to o) and where it exists."""
        if self.params.projection == "box":
            return x + R * box_t, B.isfinite(box_t)
        rho = float(np.mean(analytic.box_hit_t(np.tile(c, (512, 1)), fibonacci_directions(512), lo, hi)))
        L = x - V3(*(x.x * 0.0 + float(a) for a in c))
        b = L.dot(R)
        disc = b * b - (L.dot(L) - rho * rho)
        t = -b + B.sqrt(B.maximum(disc, 0.0))
        return x + R * t, (disc >= 0.0) & (t > 0.0)

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        p = self.params
        P = env.need_probes(self.name, self.spec()) or _Only(env)
        lo, hi = room_box(B, env)
        zero = x.x * 0.0
        ok = B.isfinite(B.length(x)) & B.isfinite(B.length(R))
        x = V3(*(B.select(ok, a, zero) for a in (x.x, x.y, x.z)))
        R = V3(*(B.select(ok, a, zero + 1.0) for a in (R.x, R.y, R.z)))
        # ------------------------------------------------------------- influence and weights
        half = self._half(lo, hi)
        ndf = []
        for c in P.centres[1:]:
            d = [B.abs(a - float(ci)) for a, ci in zip((x.x, x.y, x.z), c)]
            if p.influence == "box":
                nd = [_ndf(B, a, float(h) - p.blend, p.blend) for a, h in zip(d, half)]
                ndf.append(B.maximum(B.maximum(nd[0], nd[1]), nd[2]))
            else:
                r = B.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                ndf.append(_ndf(B, r, float(np.linalg.norm(half)) - p.blend, p.blend))
        # ------------------------------------------------------------- each probe's answer
        t = None  # the ray's exit from the room box, shared by every box-projected probe
        for xi, Ri, a, b in ((x.x, R.x, lo[0], hi[0]), (x.y, R.y, lo[1], hi[1]), (x.z, R.z, lo[2], hi[2])):
            plane = B.select(Ri > 0.0, zero + float(b), zero + float(a))
            ti = B.select(Ri == 0.0, zero + 3e38, (plane - xi) / B.select(Ri == 0.0, zero + 1.0, Ri))
            t = ti if t is None else B.minimum(t, ti)
        inside = ok
        for xi, a, b in zip((x.x, x.y, x.z), lo, hi):
            inside = inside & (xi >= float(a)) & (xi <= float(b))
        t = B.select(inside, t, zero + float("nan"))
        # ------------------------------------------------------------- the weights, before any lookup
        projected = [self._project(B, x, R, c, lo, hi, t) for c in P.centres]
        usable = [okk & inside for _, okk in projected]
        ndf = [B.select(u, d, zero + 1.0) for u, d in zip(usable[1:], ndf)]  # no answer: no influence
        w, w0 = blend_weights(B, ndf)
        w = [B.select(usable[0], w0, zero) if w0 is not None else B.select(usable[0], zero + 1.0, zero)] + w
        # ------------------------------------------------------------- each probe's answer
        # a probe k ≥ 1 of weight 0 is not read, nor is its answer made (a branch: a GPU warp none of whose rays
        # weighs it skips the probe): its answer is used nowhere (shown is a probe of weight > 0, or probe 0's;
        # ghosting needs GHOST_WEIGHT) and its radiance is weighed by 0, so 0 stands for both
        answers, rads, tols = [], [], []
        for k, (c, (pk, _)) in enumerate(zip(P.centres, projected)):
            read = usable[k] if k == 0 else usable[k] & (w[k] > 0.0)

            def answer(vx, vy, vz, k=k, c=c):  # probe k's answer and radiance in direction v from its centre
                v = V3(vx, vy, vz)
                ch = P.lookup(vx * 0.0 + float(k), v)
                a = V3(*(vx * 0.0 + float(ci) for ci in c)) + B.normalize(v) * ch[3]
                return (a.x, a.y, a.z, *ch[:3], B.maximum(ch[3] * (2.0 / max(P.res, 1)), 0.01))

            # an unread lane looks (1, 1, 1), finite (numpy runs both sides of a branch its lanes split)
            v = pk - V3(*(zero + float(a) for a in c))
            v = tuple(B.select(read, a, zero + 1.0) for a in (v.x, v.y, v.z))
            out = B.branch(read, v, answer, lambda vx, vy, vz: (vx * 0.0,) * 7)
            answers.append(V3(*out[:3]))
            rads.append(V3(*out[3:6]))
            tols.append(out[6])
        # ------------------------------------------------------------- blend, dominant probe, ghosting
        best, best_w = zero, zero - 1.0
        for k, wk in enumerate(w):
            more = wk > best_w
            best, best_w = B.select(more, zero + float(k), best), B.select(more, wk, best_w)
        shown = V3(zero, zero, zero)
        rad = V3(zero, zero, zero)
        for k, (a, r, wk) in enumerate(zip(answers, rads, w)):
            me = best == float(k)
            shown = V3(*(B.select(me, u, s) for u, s in zip((a.x, a.y, a.z), (shown.x, shown.y, shown.z))))
            rad = rad + r * wk
        ghost = ~ok & ok
        spent = zero
        for a, wk, tol in zip(answers, w, tols):
            ghost = ghost | ((wk >= GHOST_WEIGHT) & (B.length(a - shown) > tol))
            spent = spent + B.select(wk > 0.0, zero + 1.0, zero)
        valid = ok & (best_w > 0.0)
        v = V3(*(B.select(valid, a, b) for a, b in zip((shown.x, shown.y, shown.z), (R.x, R.y, R.z))))
        ratio = B.length(v) / env.distance(v)  # diagnostic: 1 on the impostor
        return Found(shown, shown, rad, ratio, valid, spent, flags={GHOST: ghost & valid})

    def lookups_per_ray(self, res: int | None = None) -> float:
        p = self.params
        return 1 + (len(p.points) if p.points is not None else int(np.prod(p.grid)))

    def colour_lookups(self, res: int | None = None) -> float:
        # every probe read is a colour (its radiance, blended) and a distance (its answer)
        return self.lookups_per_ray(res)
