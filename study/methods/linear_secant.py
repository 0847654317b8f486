"""Linear search then secant steps (Umenhoffer, Patow, Szirmay-Kalos, GPU Gems 3 ch. 17, 2007), the linear search
marched texel by texel.

The ray x + R d is parameterized by t ∈ [0, 1]: d(t) = a t / (1 − t) with a = |x|, so that the ray point is
p(t) / (1 − t) with p(t) = (1 − t) x + t a R; as t runs from 0 to 1 the lookup direction p̂(t) walks the
great-circle arc from x̂ to R on the direction sphere.

The surface test is written on p, which stays finite up to t = 1 (the point at infinity in direction R):
g(t) = |p(t)| − (1 − t) |p(t)'| (|v'| the stored distance towards v), g < 0 in front of the environment surface
("undershoot", the paper's |l|/|l'| < 1), g > 0 behind it. g(1) = a > 0, so every ray that starts in front of the
surface has a crossing.

Phases (both from the search core :mod:`study.methods.search`): (1) linear search for the FIRST pair of consecutive
samples with g < 0 then g ≥ 0, on samples in equal angles along the arc (:func:`~study.methods.search.arc_samples`)
no farther apart than 1/``steps_per_texel`` texels: a texel spans at least about 1/res radians of the cube map
(0.94/res at a face's corners, 1/res at its edge midpoints, 2/res at its centre), so n = ⌈π res
``steps_per_texel``⌉ steps cover a half turn (the longest arc) and no crossing wider than a texel lies between two
samples (uniform steps in t, as in the chapter, turn the direction by up to 1/cos²(θ/2) times more in the middle of
a long arc than at its ends, and steps over thin crossings); n is capped at ``max_steps`` (the step then grows);
(2) ``secant_steps`` secant (false-position) steps on g inside that bracket, keeping the side by the sign of g, by
default with the Illinois rule (when the same end is replaced twice in a row, the other end's g is halved; plain
false position stalls on one side and left errors of centimetres after 10 steps on a column face); the result is
the secant point of the final bracket. The secant works on g(t) instead of the chapter's q(d) because q is infinite
at t = 1; both vanish at the same points. Invalid (NaN shown point) where no crossing is found (x itself behind the
environment surface and the ray never comes out in front of it).

Hierarchical search (``hierarchical``, default): the same samples, but blocks of them that the impostor's min
pyramid (:mod:`study.impostor.pyramid`) proves to lie in front of the surface (the ray point nearer to o than any
distance the lookups there could read) are skipped in one lookup, and a ray stops at its crossing
(:class:`study.methods.march.Skip`): the same bracket as the texel march, from tens of lookups instead of n.
``hierarchical=False`` is the texel march itself, kept as the brute-force twin the tests compare with.

Cost: the texel march runs all n steps on every ray (a ray whose arc ends earlier repeats t = 1): g(0), n steps,
``secant_steps`` and the shown point, 1 + n + secant_steps + 1 on every ray. The hierarchical search reports what
each ray spent (``Localization.lookups``: pyramid reads and samples read, plus one re-read of the bracket's start);
:meth:`LinearSecant.lookups_per_ray` is the bound of either (n from the cube resolution; ``max_steps`` when it is
not given; for the hierarchical search at most 2n + log₂ n + 3 in place of n).

Open environments: samples whose texel holds FAR (no surface) are undershoots, so a ray that leaves the scene
finds no crossing; :meth:`Method.trace` then lets it escape when its direction R sees no surface from o.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor import cubemap
from study.impostor.views import Captured
from study.methods.base import Knob, Localization, Method, register
from study.methods.march import Look, Skip, iterations
from study.methods.search import arc_samples, first_crossing, refine, secant_point


class TexelMarchParams(BaseModel):
    """The linear search's sampling (shared with ``layered``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    steps_per_texel: Annotated[
        float, Field(gt=0, le=16, description="samples per texel of arc (≥ 1: no crossing stepped over)")
    ] = 1.0
    max_steps: Annotated[int, Field(ge=1, le=65536, description="cap on the steps of a half-turn arc")] = 4096
    hierarchical: bool = Field(
        True, description="skip what the impostor's min pyramid proves empty (False: read every sample)"
    )


#: The face edges a half-turn arc is cut at, found before the march: a half turn of a great circle crosses 2 or 3
#: (3000 random circles: 2 on 64 %, 3 on 36 %); were there more, blocks past the last would not be cut, which
#: costs lookups, never a crossing.
EDGES = 3
#: A partial jump's safety against float rounding (~1e-7 rad in the angles, where a sample is 4e-3 rad apart at
#: n = 805): the bound is lowered by this fraction and the jump ends 10 · SAFE samples short of where the ray point
#: reaches it.
SAFE = 1e-3
#: The pyramid read's divisions as approximate reciprocals (:meth:`study.backend.Backend.rcp`: on CUDA one
#: instruction for the eight of an IEEE division; the march issues instructions rather than waiting on reads): the
#: block end's face coordinates (the box is dilated by 1e-3 texel, the reciprocal is off by ~3e-7) and the partial
#: jump's h/b (SAFE's 1e-3 covers it). What the march proves stays proven, so the bracket is the same; which blocks
#: it proves can differ at a box's edge, so the lookups can. Never the sample read's Look (g is read there).
ROUGH = True


def skipper(B, pyramid, x, R, a, n: int, base=None) -> Skip | None:
    """The :class:`~study.methods.search.Skip` of a march of ``n`` samples (:func:`arc_samples`) along
    p(t) = (1 − t) x + t a R over a distance map with a min pyramid (:class:`study.impostor.pyramid.MinPyramid`),
    its blocks cut at the cube's face edges; None without a pyramid (an analytic environment). ``base``: the
    map's first face in a stack of maps (:meth:`~study.impostor.pyramid.MinPyramid.bound_along`)."""
    if pyramid is None:
        return None

    # ----------------------------------------------------------------- the arc's great circle
    # d(φ) = cos φ e₁ + sin φ e₂ from x̂ towards R, reached at φ = θ; sample j at φ_j = j π/n. The ray point seen in
    # direction d(φ) lies at r(φ) = h / sin(θ − φ) from o, h = |x| sin θ (the law of sines in the triangle o, x,
    # point): convex along the ray, so the points nearer than b form one stretch of it.
    e1 = x / a
    cos = e1.dot(R)
    sin = B.sqrt(B.maximum(1.0 - cos * cos, 0.0))
    e2 = (R - e1 * cos) / B.maximum(sin, 1e-12)
    theta = B.acos(B.minimum(B.maximum(cos, -1.0), 1.0))
    h = a * sin  # the ray's closest approach to o
    turning = sin > 1e-6  # the ray is not along x̂ (no plane of its own: only whole blocks are cleared)
    theta_q, full = theta - (math.pi / 2), a * 0.0 + float(n)  # made once, not per step

    # the ray point at t and its face coordinates (pyramid.bound_along's); rough: u, v to within ~3e-7
    # (cubemap.face_uv's rough), for a block's end, whose box the pyramid dilates by 1e-3 texel
    def look(t, rough=False):
        rest = 1.0 - t
        p = x * rest + R * (a * t)  # p(t)
        face, u, v = cubemap.face_uv(B, p.x, p.y, p.z, rough=rough)
        return Look(t, p, B.length(p), face + base if base is not None else face, u, v, rest)

    def reach(k, kb, ta, tb):
        # the last sample of k + 1 … kb (at t_a … t_b; t_a may be its Look) proven in front of every lookup the
        # pyramid bounds
        la = ta if isinstance(ta, Look) else look(ta)
        lb = look(tb, rough=ROUGH)  # (not la: the sample read reads g at it)
        b = pyramid.bound(la.face, la.u, la.v, lb.face, lb.u, lb.v)
        near_a = la.length < la.rest * b  # |p|/(1 − t) < b: the ray point nearer than every lookup
        whole = near_a & (lb.length < lb.rest * b)
        # part of the way: from a near start, r(φ) < b' while θ − φ > asin(h/b'), b' = (1 − SAFE) b
        # (rough: c' = h/b' exceeds h/b by SAFE, 1e-3 relative, far above the reciprocal's 3e-7, so φ stays below
        # where the ray point reaches b)
        bs = B.maximum(b * (1.0 - SAFE), 1e-30)
        c = B.minimum(h * B.rcp(bs) if ROUGH else h / bs, 1.0)
        phi = theta_q + B.acos(c)  # θ − asin(c)
        last = -1.0 - B.floor(10.0 * SAFE - phi * (n / math.pi))  # the last φ_j below φ by 10 SAFE samples
        part = B.select(near_a & (b > 0.0) & turning, B.minimum(B.maximum(last, k), kb), k)
        return B.select(whole, kb, part)

    # ----------------------------------------------------------------- where the arc's samples change face
    def last_on_face(k):  # the last sample on the face of sample k + 1 (n: the arc's end is on it)
        phi_e = cubemap.exit_angle(B, e1, e2, (k + 1.0) * (math.pi / n))  # where the circle leaves that face
        last = B.maximum(-B.floor(-phi_e * (n / math.pi)) - 1.0, k + 1.0)  # the last φ_j < φ_e
        return B.select((phi_e >= theta) | ~turning, last * 0.0 + float(n), last)  # past θ: all at R

    ends, k = [], x.x * 0.0
    for _ in range(EDGES):  # before the march: its loop only selects
        k = last_on_face(k)
        ends.append(B.minimum(k, full))  # ≤ n: the march's blocks need no cut at n then

    def edge(k):  # the first end at or after sample k + 1 (n past the last one found): k < e, k whole
        out = full
        for e in reversed(ends):
            out = B.select(k < e, e, out)
        return out

    return Skip(reach, edge, look)


def march_bound(res: int | None, p: TexelMarchParams) -> int:
    """The most lookups per function of the linear search (without g(0)): n samples, or with ``hierarchical``
    the march's iterations and the re-read of the bracket's start (:func:`study.methods.march.iterations`)."""
    n = march_steps(res, p)
    return iterations(n) + 1 if p.hierarchical and res != 0 else n


def march_steps(res: int, p: TexelMarchParams) -> int:
    """Steps for a half-turn arc at cube resolution ``res``: ⌈π res steps_per_texel⌉, at most ``max_steps``
    (``max_steps`` where the map has no texels, as an analytic environment)."""
    if not res:  # (also None: the resolution is not known)
        return p.max_steps
    return max(1, min(p.max_steps, math.ceil(math.pi * res * p.steps_per_texel)))


class Params(TexelMarchParams):
    secant_steps: Annotated[int, Field(ge=0, le=100, description="secant steps after the linear search")] = 4
    illinois: bool = Field(True, description="Illinois rule against one-sided stagnation of the secant steps")


@register
class LinearSecant(Method):
    name = "linear_secant"
    Params = Params
    knob = Knob("steps_per_texel", (0.25, 0.5, 1.0, 2.0))  # below 1, thin crossings can fall between samples

    def localize(self, B: Backend, env: Captured, x: V3, R: V3) -> Localization:
        p = self.params
        # ------------------------------------------------------------- parameterization and samples
        xl = B.length(x)  # |x|
        a = B.maximum(xl, 1e-6)  # a = |x| (kept > 0: rays from o walk along R itself)
        cos = x.dot(R) / a  # x̂·R
        n = march_steps(env.res, p)

        def g(t):
            pt = x * (1.0 - t) + R * (a * t)  # p(t)
            return B.length(pt) - (1.0 - t) * env.distance(pt)

        # ------------------------------------------------------------- linear search for the first crossing
        zero = xl * 0.0
        g0 = g(zero)
        pyr = getattr(getattr(env, "impostor", env), "pyramid", None) if p.hierarchical else None
        skip = skipper(B, pyr, x, R, a, n)
        if skip is not None:  # g at the march's Look: the same operations as g(t)
            imp = getattr(env, "impostor", env)
            skip.value = lambda L: L.length - L.rest * B.sample(imp.dist, L.face, L.u, L.v)[0]
        # bracket: last undershoot, first overshoot (no crossing: the whole arc, t = 0 to the point at infinity)
        br = first_crossing(
            B, g, zero, g0, arc_samples(B, cos, n), n, t_max=1.0, default=(zero, g0, zero + 1.0, a), skip=skip
        )
        spent = zero + float(n) if skip is None else skip.lookups

        # ------------------------------------------------------------- secant steps inside the bracket
        br = refine(B, g, br, p.secant_steps, illinois=p.illinois, rising=True)
        t = secant_point(br)
        l = (x * (1.0 - t) + R * (a * t)) / B.maximum(1.0 - t, 1e-7)  # x + R d(t)
        # lookups before the shown point's: g(0), the linear search, the secant steps
        return Localization(l=l, valid=br.found & B.isfinite(t), lookups=spent + float(1 + p.secant_steps))

    def lookups_per_ray(self, res: int | None = None) -> float:
        # g(0), the linear search (texel march: all n samples on every ray), the secant steps, the shown point
        return 1 + march_bound(res, self.params) + self.params.secant_steps + 1
