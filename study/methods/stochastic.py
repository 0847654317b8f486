"""Stochastic glossy reflections: N half vectors importance-sampled from the GGX lobe per ray, each reflected ray
localized by the paper's search (``localized``) and looked up, averaged with the weights G (v·h)/((n·h)(n·v))
(self-normalized; :mod:`study.impostor.ggx`). As N grows it converges to the lobe integral over what the search
finds — the ray-traced answer where the search finds the exact hits: the upper bound of the glossy methods.

``localize = false`` looks every sample up in its own direction from the reference point: the GGX convolution of
the impostor *without* the split sum's assumption v = n (the reference of the prefiltering error). The samples are
seeded (``seed``, with the case's ``render.seed`` mixed in where it is not 0: a figure's seeds draw them anew) and
drawn on the host, one set per ray. Its shown point is the ``localized`` hit of the mirror direction R. At α = 0
every sample is R: it is ``localized``. Open environments: as ``localized``.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study import progress
from study.backend import V3, Backend
from study.impostor import ggx
from study.impostor.views import Captured
from study.methods.base import Found, Knob, register
from study.methods.glossy import GlossyMethod, eye
from study.methods.localized import Localized


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    samples: Annotated[int, Field(ge=1, le=4096, description="GGX samples per ray (N)")] = 16
    iterations: Annotated[int, Field(ge=0, le=1000, description="false-position steps of each search")] = 10
    localize: Annotated[
        bool, Field(description="search each sample's hit (false: look it up from the reference point)")
    ] = True
    seed: Annotated[int, Field(ge=0, le=2**31 - 1, description="seed of the samples")] = 0


@register
class Stochastic(GlossyMethod):
    name = "stochastic"
    Params = Params
    knob = Knob("samples", (1, 4, 16, 64, 256))

    def _search(self) -> Localized:
        return Localized(iterations=self.params.iterations)

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        p, lobe = self.params, env.need_lobe(self.name, R)
        n = lobe.normal
        v = eye(n, R)
        M = B.shape_of(x.x)[1]
        rng = np.random.default_rng((p.seed, lobe.seed) if lobe.seed else p.seed)  # the case's seed mixed in
        m = self._search()
        per = m.lookup_bound(env.res) - 1  # a search's lookups before its read
        # ------------------------------------------------------------- the mirror direction: the shown point
        loc = m.localize(B, env, x, R)
        dist = env.distance(loc.l)
        lhat = B.normalize(loc.l)
        spent = (loc.lookups if loc.lookups is not None else x.x * 0.0 + per) + 1.0
        # ------------------------------------------------------------- N lobe samples, each localized
        acc, wsum = [x.x * 0.0] * 3, x.x * 0.0
        for _ in range(p.samples):
            progress.checkpoint()  # samples × iterations can outlast --max-minutes: stop inside the stage
            u = rng.random((2, M))
            h = ggx.half_vectors(lobe.alpha, u[0], u[1])
            l_dir, w = ggx.lobe_directions(B, n, v, tuple(B.array(h[:, i]) for i in range(3)), lobe.alpha)
            if p.localize:
                s = m.localize(B, env, x, l_dir)
                look = s.l
                spent = spent + (s.lookups if s.lookups is not None else x.x * 0.0 + per) + 1.0
            else:
                look = l_dir
                spent = spent + 1.0
            r, g, b, _ = env.lookup(look)
            w = B.select(B.isfinite(r + g + b), w, w * 0.0)
            acc = [a + B.select(w > 0.0, c * w, w * 0.0) for a, c in zip(acc, (r, g, b))]
            wsum = wsum + w
        r0, g0, b0, _ = env.lookup(loc.l)  # no sample above the surface (grazing): the mirror direction
        some = wsum > 0.0
        safe = B.maximum(wsum, 1e-30)
        rad = V3(*(B.select(some, a / safe, c) for a, c in zip(acc, (r0, g0, b0))))
        return Found(loc.l, lhat * dist, rad, B.length(loc.l) / dist, loc.valid, spent)

    def lookups_per_ray(self, res: int | None = None) -> float:
        one = self._search().lookups_per_ray(res) if self.params.localize else 1
        return self._search().lookups_per_ray(res) + self.params.samples * one

    def host_steps(self, res: int | None = None) -> float:
        return self.lookups_per_ray(res)  # samples × the search's iterations, each a step over all rays
