"""The exact hit shaded from a hit-lighting cache (``hit_cache``): how engines shade a hit they found without
tracing on — Lumen's surface cache, AMD GI-1.x's world-space hash grid. The hit is the exact one (``traced``'s
query: zero wrong hits), its radiance the value a world-space grid of ``res`` cells along the environment's
longest side holds there (:mod:`study.impostor.hitcache`: six normal bins per cell, filled from path-traced
surface samples).

What it is for: the *hit lighting* term of the error, measured by its own experiment — the same exact hits,
shaded from the cache (this row) and exactly (``traced``), against the same truth: this row's error against the
truth is the cache's alone (up to the two renders' noise), and ``res`` is its knob. A ray that leaves the scene reads
the exact radiance along it (no surface, nothing to cache), so open scenes add nothing to the term.

Cost: one lookup per ray (the cache read) on top of the exact query, priced in ``study bench`` as ``traced``.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor.views import Captured, Views
from study.methods.base import Found, Knob, register
from study.methods.traced import ExactQuery


class HitCacheParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    res: Annotated[
        int, Field(ge=1, le=1024, description="cache cells along the environment's longest side")
    ] = 32


@register
class HitCache(ExactQuery):
    name = "hit_cache"
    in_all = False  # an experiment of its own (configs/fig_hitcache.toml): "all" leaves it out
    Params = HitCacheParams
    knob = Knob("res", (4, 8, 16, 32, 64, 128))  # cache cells along the environment's longest side
    shades_hit = False  # its shading is the cache read, priced as fetches (study.bench.run.exact_query_row)

    def views_needed(self) -> Views:
        return Views(hits=True, shade=True, caches=(self.params.res,))

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        hits, cached = env.need_hits(self.name), env.need_cached(self.name)
        if hits is None or cached is None:  # a bare impostor: the room box's exact hit, as traced
            return self._box(B, env, x, R)
        shade = env.need_shade(self.name)

        def radiance(xw, d, escapes):
            r = cached(self.params.res, xw, d)
            if escapes.any():  # no surface to cache: the radiance along the ray
                r[escapes] = shade(xw[escapes], d[escapes])
            return r

        return self._exact(B, env, x, R, radiance)
