"""The exact query for rough objects (``traced_glossy``): the lobe's rays traced, as a hardware ray tracer would
shade a glossy reflection. Per secondary ray (x, mirror direction R) leaving a surface of GGX roughness α with
normal n (``Captured.lobe``), ``samples`` = K half vectors are importance-sampled from the lobe (seeded, one set per
ray, :func:`study.impostor.ggx.half_vectors`), each reflected ray is traced exactly and its hit shaded exactly
(``Captured.shade``: the radiance arriving along it, path traced by Mitsuba in the scene without the object, with
exact shading's own seed: the lobe's rays are not the case's exact rays, whose truth ``traced`` reads), and the
K radiances are averaged with the weights G (v·h)/((n·h)(n·v)) (self-normalized): the estimator of the glossy
truth (:func:`study.measure.truth.lobe_at_hit`, 16 directions) at a budget of K traced rays per pixel. Its shown
point is the exact hit of R (outcome columns: zero wrong hits); a ray whose K samples all fall below the surface
(grazing) shows the radiance along R.

What it is for: the row that answers "would tracing the lobe's rays be cheaper?" on the glossy tables. Its error
against the truth is the lobe's sampling noise at K rays (falling as 1/√K) and the renders' noise; ``samples`` is
its knob, so ``study pareto`` draws its error against K queries' time. Like ``traced`` it reads no cube map, so its
rows leave out the oracle's and the split's columns (``reads_views``).

Cost: K lookups per ray (the K hits' radiance reads); ``study bench`` does not time its Python path: its price is
K times the exact query's (:attr:`queries` × :data:`ExactQuery.bench_query`, ``study pareto``'s ``exact_priced``),
the shading of the hits not counted, as for ``traced``. The R hit is for the outcome columns only (not priced).

On a bare impostor (no exact tracer, no lobe: the analytic tests' fallback) it is its mirror twin ``traced``
(the room box's exact hit).
"""

from __future__ import annotations

from typing import Annotated, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study import backend as backends
from study.backend import V3, Backend
from study.impostor import ggx
from study.impostor.views import Captured
from study.methods.base import Found, Knob, register
from study.methods.glossy import eye
from study.methods.traced import ExactQuery


class TracedGlossyParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    samples: Annotated[int, Field(ge=1, le=1024, description="lobe rays traced per secondary ray (K)")] = 4
    seed: Annotated[int, Field(ge=0, le=2**31 - 1, description="seed of the lobe samples")] = 0


@register
class TracedGlossy(ExactQuery):
    name = "traced_glossy"
    glossy: ClassVar[bool] = True  # a method for rough objects: methods = "glossy" selects it
    Params = TracedGlossyParams
    knob = Knob("samples", (1, 4, 16))
    bench_query: ClassVar[str] = "ray_intersect_preliminary"

    @property
    def queries(self) -> int:
        """Exact queries per ray the image needs: K (the price ``study pareto`` gives it)."""
        return self.params.samples

    def lookups_per_ray(self, res: int | None = None) -> float:
        return self.params.samples  # the K hits' radiance reads; the ray queries are no cube-map lookups

    def search(self, B: Backend, env: Captured, x: V3, R: V3) -> Found:
        if env.need_hits(self.name) is None:  # a bare impostor: the mirror twin
            return self._box(B, env, x, R)
        lobe, shade = env.need_lobe(self.name, R), env.need_shade(self.name)
        avg = self.lobe_average(B, env.origin(), x, R, lobe, shade)
        ok = np.isfinite(B.to_numpy(x)).all(-1) & np.isfinite(B.to_numpy(R)).all(-1)  # the rays _exact shades
        f = self._exact(B, env, x, R, lambda xw, d, escapes: avg[ok])
        return Found(f.l, f.shown, f.radiance, f.ratio, f.valid, x.x * 0.0 + float(self.params.samples))

    def lobe_average(self, B: Backend, o: np.ndarray, x: V3, R: V3, lobe, shade) -> np.ndarray:
        """(N, 3) float64: the weighted mean of the radiance along K lobe directions per ray (module docstring),
        NaN on rays with a non-finite origin or direction."""
        N = backends.get("numpy")
        xw = B.to_numpy(x).astype(np.float64) + o
        r = B.to_numpy(R).astype(np.float64)
        n = B.to_numpy(lobe.normal).astype(np.float64) * np.ones_like(r)
        ok = np.isfinite(xw).all(-1) & np.isfinite(r).all(-1) & np.isfinite(n).all(-1)
        out = np.full_like(xw, np.nan)
        if not ok.any():
            return out
        nv, rv = N.vec(n[ok]), N.vec(r[ok])
        v = eye(nv, rv)
        M, K = int(ok.sum()), self.params.samples
        u = np.random.default_rng((self.params.seed, 11)).random((K, 2, M))
        d, W = ggx.lobe_samples(N, nv, v, lobe.alpha, u)
        L = np.asarray(shade(np.tile(xw[ok], (K, 1)), d), np.float64).reshape(K, M, 3)
        W = np.where(np.isfinite(L).all(-1, keepdims=True), W, 0.0)
        num, den = (np.where(W > 0, L, 0.0) * W).sum(0), W.sum(0)
        if (den == 0).any():  # no sample above the surface (grazing): the radiance along R
            num = np.where(den > 0, num, np.asarray(shade(xw[ok], r[ok]), np.float64))
            den = np.where(den > 0, den, 1.0)
        out[ok] = num / den
        return out
