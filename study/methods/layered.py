"""Layered distance maps (GPU Gems 3 ch. 17; Hakura and Snyder 2001): all depth layers marched together, texel by
texel, and the first entry into a solid kept.

Layers come from ``Captured.layers`` (:mod:`study.impostor.layers`: layer k holds the (k+1)-th surface seen from the
reference point o, channels R, G, B, jump, distance); on a bare impostor without layers, the impostor itself is
the only layer (a caller that captures views and lacks them is a StudyError).

Search: the linear search of :mod:`study.methods.linear_secant` (the t = d/(d + a) parameterization, samples in equal
angles along the arc, no farther apart than 1/``steps_per_texel`` texels, n = ⌈π res ``steps_per_texel``⌉ for a half
turn, at most ``max_steps``) on every layer's g_k(t) = |p(t)| − (1 − t) |p(t)'|_k at once. Layers are nested
(g_0 ≥ g_1 ≥ …): at each sample, c = the number of layers the ray point is behind, and the point is *inside* a solid
where c is odd (behind a surface that faces o, in front of the next, which faces away: a column between its front
face and its top seen from below), or behind every layer where the last repeats the one before (the room's wall).
The hit is the first step from outside to inside (:func:`study.methods.search.first_entry`): on layer c where the
point went behind it (a surface facing o), on layer c − 1 where it came back in front of it (a surface facing away
from o, such as a column top seen from below, which is how a layer behind the first holds it). That is the
rejection of depth jumps: the *skin* that bilinear interpolation stretches from a silhouette to what lies behind it
makes a ray passing behind the silhouette go behind two layers within a texel or two (inside, then out on the far
side). An entry is dropped when the ray leaves to the far side within ``hold`` texels of arc; kept when it stays
inside that long, or when it comes back out in front (it clipped an edge) and then nothing changes for ``hold``
texels (the skin is a saddle that a ray can cut twice within a texel). The kept entry's layer is refined by
``iterations`` Illinois secant steps (search core :func:`~study.methods.search.refine`); one lookup at the refined
point reads the shown point's distance and radiance on that layer (:meth:`Layered.search`). valid: an entry was
found.

Why not the paper's false position on each layer: on the layer that holds a column top (seen from below), a ray
coming down onto the top first crosses the skin along the top's silhouette edge and then the top itself; false
position converges on the skin (the first root of its first bracket) and never reaches the top (see
tests/methods/test_methods_layered.py). Why not the first two sign changes of each layer, each tested against the jump
channel, nearest clean one kept: a uniform 30-step search in t steps over the thin
crossing near the column's top edge on 45 % of the rays whose hit o does not see (fig5 p0); with 2000 steps 14 %
stay wrong, as the jump test rejects true top hits within a texel of the edge and a third crossing goes unrecorded;
the entry rule leaves 2.4 % (scripts/compare_layered.py).

Hierarchical search (``hierarchical``, default): blocks of samples in front of the nearest layer (then in front of
every layer: c = 0, outside) that layer 0's min pyramid proves so are skipped in one lookup, a ray reads sample by
sample while an entry is pending, and stops at its kept entry (:class:`study.methods.march.Skip`); the entry is the
texel march's (``hierarchical=False``, kept as the tests' brute-force twin).

Cost: every layer is looked up at every sample read and, since the kept layer differs between rays, at every
secant step and at the final lookup: with the texel march layers × (1 + n + iterations + 1) on every ray; the
hierarchical search reports what each ray spent (one lookup per pyramid read, one per layer per sample read and
for the re-read of the bracket's start). :meth:`Layered.lookups_per_ray` is the bound of either (n from the cube
resolution; ``max_steps`` when it is not given).

Open environments: no-surface texels hold FAR in every layer, so such rays find no entry into a solid and
escape in the finishing step of :meth:`Method.trace`, as for ``linear_secant``.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import Field

from study.backend import V3, Backend
from study.impostor import cubemap
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured
from study.methods.base import Found, Knob, TracingMethod, register
from study.methods.linear_secant import TexelMarchParams, march_bound, march_steps, skipper
from study.methods.search import arc_samples, first_entry, refine, secant_point


class Params(TexelMarchParams):  # + steps_per_texel, max_steps
    layers: Annotated[int, Field(ge=1, le=16, description="depth layers searched")] = 3
    iterations: Annotated[int, Field(ge=0, le=1000, description="secant steps on the kept entry")] = 10
    hold: Annotated[
        float,
        Field(ge=0, le=64, description="texels of arc that decide whether an entry into a solid is kept"),
    ] = 4.0


def _one(B, e, K: int, read, i: int = 0) -> list:
    """read(e) per ray (e an array of layer indices; read(i) an array or a list of them for layer i): each ray
    reads its own layer alone (nested branches: one lookup, not K)."""
    if i == K - 1:
        return _listed(read(i))
    return list(
        B.branch(e == float(i), (e,), lambda e: _listed(read(i)), lambda e: _one(B, e, K, read, i + 1))
    )


def _listed(v) -> list:
    return list(v) if isinstance(v, (list, tuple)) else [v]


@register
class Layered(TracingMethod):
    name = "layered"
    Params = Params
    knob = Knob("steps_per_texel", (0.25, 0.5, 1.0, 2.0))  # below 1, thin crossings can fall between samples

    def layers_needed(self) -> int:
        return self.params.layers

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        """The kept entry's point, read on its layer (distance and radiance)."""
        p = self.params
        maps = env.need_layers(self.name, p.layers)
        # ------------------------------------------------------------- parameterization and samples
        xl = B.length(x)
        a = B.maximum(xl, 1e-6)  # a = |x|
        cos = x.dot(R) / a  # x̂·R
        res = getattr(maps[0], "res", 0)
        n = march_steps(res, p)
        per_texel = n / (math.pi * res) if res else p.steps_per_texel  # samples per texel after the cap
        hold = round(p.hold * per_texel)  # in samples
        zero = xl * 0.0

        def point(t):  # p(t) = (1 − t) x + t a R
            return x * (1.0 - t) + R * (a * t)

        shared = all(isinstance(m, EnvMap) and m.res == res for m in maps)  # one face/uv for every layer

        K = len(maps)

        def reader(t):  # read(i): g_i(t), one lookup of layer i
            pt = point(t)
            lp = B.length(pt)
            if shared:
                face, u, w = cubemap.face_uv(B, pt.x, pt.y, pt.z)
                return lambda i: lp - (1.0 - t) * B.sample(maps[i].dist, face, u, w)[0]
            return lambda i: lp - (1.0 - t) * maps[i].distance(pt)

        def gs(t):
            read = reader(t)
            return [read(i) for i in range(K)]

        def read_at(L):  # reader(L.t) from the hierarchical march's Look (the same operations, one face_uv)
            if shared:
                return lambda i: L.length - L.rest * B.sample(maps[i].dist, L.face, L.u, L.v)[0]
            return lambda i: L.length - L.rest * maps[i].distance(L.p)

        # layer 0, the others only behind it (in front of it g_0 < 0 stands for all)
        def gs_lazy(t, read=None):
            read = reader(t) if read is None else read
            g0 = read(0)
            if K == 1:
                return [g0]
            rest = B.branch(
                g0 >= 0.0, (g0,), lambda g0: [read(i) for i in range(1, K)], lambda g0: [g0] * (K - 1)
            )
            return [g0, *rest]

        # ------------------------------------------------------------- march: the first entry that is not skin
        # (hierarchical: blocks in front of the nearest layer skipped; g_0 ≥ g_k, so in front of every layer)
        skip = skipper(B, getattr(maps[0], "pyramid", None), x, R, a, n) if p.hierarchical else None
        if skip is not None:
            skip.value = lambda L: gs_lazy(L.t, read_at(L))
        br, e = first_entry(
            B,
            gs if skip is None else gs_lazy,
            zero,
            gs(zero),
            arc_samples(B, cos, n),
            n,
            hold=hold,
            t_max=1.0,
            default=(zero, zero - 1.0, zero + 1.0, zero + 1.0),
            skip=skip,
            cost=lambda g_0: 1.0 + (K - 1.0) * B.select(g_0 >= 0.0, zero + 1.0, zero),
        )  # harmless dummy bracket

        # ------------------------------------------------------------- secant steps on the entry's layer
        br = refine(B, lambda t: _one(B, e, K, reader(t))[0], br, p.iterations)
        t = secant_point(br)
        l = point(t) / B.maximum(1.0 - t, 1e-7)  # x + R d(t)
        ch = _one(B, e, K, lambda i: maps[i].lookup(l))  # the shown point, read on its layer alone
        dist, lhat = ch[-1], B.normalize(l)
        march = zero + float(K * n) if skip is None else skip.lookups
        spent = march + float(K + p.iterations + 1)
        shown = V3(lhat.x * dist, lhat.y * dist, lhat.z * dist)
        return Found(l, shown, V3(*ch[:3]), B.length(l) / dist, br.found & B.isfinite(t), spent)

    def lookups_per_ray(self, res: int | None = None) -> float:
        # per layer: g(0) and the linear search (texel march: all n steps on every ray); on the kept layer alone:
        # the secant steps and the final lookup
        p = self.params
        return p.layers * (1 + march_bound(res, p)) + p.iterations + 1
