"""Layered distance maps (GPU Gems 3 ch. 17; Hakura and Snyder 2001): the paper's search on every depth layer.

Layers come from ``env.info["layers"]`` (:mod:`study.layers`: layer k holds the (k+1)-th surface seen from the
reference point, channels R, G, B, jump, distance); on a bare impostor without layers, the impostor itself is the
only layer (and the method is ``localized``).

For each of the first ``layers`` layers, the paper's false-position search (``localized`` with ``iterations``,
``band_lo``, ``band_hi``) gives a lookup vector l_k; one more lookup at l_k reads q_k = |l_k|/|l_k'|, the layer's
relative depth jump and the radiance. A layer's hit is
- *converged* where |q_k − 1| ≤ ``tolerance``, l_k is finite and lies ahead on the ray ((l_k − x)·R > 0);
- *clean* where it is converged and the jump is below ``max_jump`` (not on the skin that bilinear interpolation
  stretches across a depth discontinuity, e.g. from a column's silhouette to the wall behind it).
The kept hit is the nearest clean one along the ray; where no layer is clean, the nearest converged one; where no
layer converged, the first layer's estimate (exactly what ``localized`` shows). valid: that estimate is finite.
The shown point and radiance come from the layer the hit was kept from (``trace`` is overridden for that).
"""
from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3
from study.methods.base import Localization, Method, Trace, register
from study.methods.localized import Localized


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    layers: Annotated[int, Field(ge=1, le=16)] = 3             # depth layers searched
    iterations: Annotated[int, Field(ge=0, le=1000)] = 10      # NITER of the search on each layer
    band_lo: Annotated[float, Field(gt=0, le=1)] = 0.999       # as localized
    band_hi: Annotated[float, Field(ge=1)] = 1.001
    tolerance: Annotated[float, Field(gt=0)] = 0.01            # |q − 1| of a converged hit
    max_jump: Annotated[float, Field(gt=0)] = 0.1              # relative depth jump above which a hit is skin


@register
class Layered(Method):
    name = "layered"
    Params = Params

    def layers_needed(self) -> int:
        return self.params.layers

    def _search(self, B, env, x, R):
        """Returns (l, valid, [r, g, b], distance) of the kept hit."""
        p = self.params
        maps = list(env.info.get("layers") or [env])[:p.layers]
        inner = Localized(iterations=p.iterations, band_lo=p.band_lo, band_hi=p.band_hi)
        big = np.float32(1e30)
        best = None
        for k, m in enumerate(maps):
            # --------------------------------------------------------- the paper's search on layer k
            l = inner.localize(B, m, x, R).l
            ch = m.lookup(l)
            dist = ch[-1]
            jump = ch[3] if m.channels == 5 else dist * 0.0
            q = B.length(l) / dist                     # |l|/|l'| on layer k
            d = (l - x).dot(R)                         # ray parameter of the hit
            conv = B.isfinite(d) & (B.abs(q - 1.0) <= p.tolerance) & (d > 0.0)
            clean = conv & (jump < p.max_jump)
            # rank: clean hits by distance, then converged ones, then the first layer's estimate
            key = B.select(clean, d, B.select(conv, d + big, dist * 0.0 + (big * 4 if k == 0 else big * 8)))
            cand = (l, ch[0], ch[1], ch[2], dist, key)
            if best is None:
                best = cand
            else:
                take = cand[5] < best[5]
                l = V3(*(B.select(take, a, b) for a, b in zip((cand[0].x, cand[0].y, cand[0].z),
                                                                  (best[0].x, best[0].y, best[0].z))))
                best = (l, *(B.select(take, a, b) for a, b in zip(cand[1:], best[1:])))
        l, r, g, b, dist, _ = best
        return l, B.isfinite(l.dot(l)) & (dist > 0.0), [r, g, b], dist

    def localize(self, B, env, x, R):
        l, valid, _, _ = self._search(B, env, x, R)
        return Localization(l=l, valid=valid)

    def trace(self, B, env, x, R):
        l, valid, rgb, dist = self._search(B, env, x, R)
        lhat = B.normalize(l)
        nan = float("nan")
        shown = V3(*(B.select(valid, c * dist, nan) for c in (lhat.x, lhat.y, lhat.z)))
        rad = V3(*(B.select(valid, c, nan) for c in rgb))
        return Trace(l, shown, rad, B.length(l) / dist, valid)

    def lookups_per_ray(self) -> int:
        # per layer: the search (|r|, |x'|, one per iteration) and one lookup at its result, which gives the
        # convergence test, the jump and the shown point's distance and radiance
        return self.params.layers * (3 + self.params.iterations)
