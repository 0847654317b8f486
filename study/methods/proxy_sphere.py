"""Parallax-corrected cube map with a sphere proxy (Bjorke 2004; spherical reflection probes).

The ray x + R d (x relative to the reference point o) is intersected with a sphere of radius ρ around the centre
c (relative to o): L = x − c, b = L·R, t = −b + sqrt(b² − (|L|² − ρ²)) (the far root, the ray leaves the sphere),
and the lookup vector is l = x + R t (the direction from o to the hit). Exact only where the environment is that
sphere.

The proxy: ``center`` (world; default o) and ``radius`` when given; otherwise the sphere around o that best fits
the room in the least-squares sense over directions: ρ = the mean distance from o to the room over the unit sphere
(the minimiser of ∫ (ρ − dist(ω))² dω), the room taken from ``Captured.room`` or, on a bare impostor, the
impostor's own stored distances. Invalid (NaN shown point) where the ray misses the sphere (x outside it, pointing
away).

Open environments: as ``proxy_box``, the proxy sphere is closed: an escaping ray is looked up in the direction of
its exit through the sphere, which sees the background in another direction.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study.backend import V3, Backend
from study.impostor import analytic
from study.impostor.views import Captured
from study.methods.base import Localization, Method, register

Vec3 = tuple[float, float, float]


class Params(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    center: Vec3 | None = Field(
        None, description="centre of the proxy sphere, world coordinates (default: o)"
    )
    radius: Annotated[float, Field(gt=0)] | None = Field(
        None, description="radius of the proxy sphere, metres (default: fitted to the room)"
    )


def fibonacci_directions(n: int) -> np.ndarray:
    """n unit directions spread evenly over the sphere (Fibonacci lattice): (n, 3)."""
    i = np.arange(n) + 0.5
    y = 1 - 2 * i / n
    r = np.sqrt(1 - y * y)
    phi = np.pi * (3 - np.sqrt(5)) * i
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], -1)


def fitted_radius(B, env, n: int = 4096) -> float:
    """ρ = mean over directions of the room's distance from o (least-squares sphere around o)."""
    w = fibonacci_directions(n)
    env = Captured.of(env)
    if env.room is not None:
        o = env.origin()
        lo, hi = (np.asarray(c, float) - o for c in env.room)
        d = analytic.box_hit_t(np.zeros_like(w), w, lo, hi)
    else:
        d = B.numpy(env.distance(B.vec(w))).astype(float)
    return float(np.mean(d))


@register
class ProxySphere(Method):
    name = "proxy_sphere"
    Params = Params

    def localize(self, B: Backend, env: Captured, x: V3, R: V3) -> Localization:
        p = self.params
        c = np.zeros(3) if p.center is None else np.asarray(p.center, float) - env.origin()
        rho = p.radius if p.radius is not None else fitted_radius(B, env)
        # ------------------------------------------------------------- far root of |L + R t| = ρ
        L = V3(x.x - float(c[0]), x.y - float(c[1]), x.z - float(c[2]))  # x − c
        b = L.dot(R)
        disc = b * b - (L.dot(L) - float(rho) ** 2)
        t = -b + B.sqrt(B.maximum(disc, 0.0))
        l = x + R * t  # hit on the proxy
        return Localization(l=l, valid=(disc >= 0.0) & (t > 0.0))

    def lookups_per_ray(self, res: int | None = None) -> float:
        return 1  # the shown point (the proxy hit is analytic)
