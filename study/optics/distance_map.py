"""The object's own distance cube map, and the far side of the object found through it (double refraction).

:class:`DistanceMap` is taken from the object's centre (:mod:`study.impostor.cubemap` convention) and holds per
texel the outward normal and the distance of the *farthest* surface point in that direction (the object's outer
envelope: for a ray inside the object, leaving the object means crossing it; directions that miss the object, as
through a torus' hole, hold distance 0).
"""

from __future__ import annotations

import numpy as np

from study import backend as backends
from study.backend import V3
from study.impostor import cubemap
from study.impostor.envmap import EnvMap
from study.methods.search import first_crossing, refine, secant_point
from study.scene.objects import ObjectGeometry, farthest_surface


class DistanceMap:
    """The object's distance cube map from its centre c: per texel the outward normal (xyz) and the distance of
    the farthest surface point (0 where the direction misses the object), bound to the backend called ``backend``
    ('numpy', 'llvm' or 'cuda'; float32 arithmetic on each).

    ``exit(p, d)`` searches each ray p + s d (p on or inside the object, world space) for the first s where
    f(s) = |l| − |l'| turns from negative to non-negative (l = p + s d − c, |l'| the map's distance towards l),
    with the search core of the methods (:mod:`study.methods.search`): ``steps`` linear steps over
    s ∈ (0, 2.1 radius] (past 2 radius the ray is outside the bounding sphere, so f > 0) bracket the crossing,
    then ``iterations`` steps of false position (the paper's eq. 3, no Illinois rule) refine it; the exit is the
    secant point of the final bracket. The start counts as inside (f(0) is taken as at most −1e-7: from a point
    on the surface, interpolation can put f(0) slightly above 0). The paper's start (eq. 2) is not used: it
    assumes a far environment and, from a point on the surface (f = 0), stays there. f is a difference, not the
    paper's ratio |l|/|l'|, since |l'| = 0 where the map is empty. The exit normal is the map's normal towards
    the exit point (the radial direction where the map holds none or one that does not face along d). Cost:
    2 + steps + iterations lookups per ray (f(0), the linear steps, the false-position steps, the normal).
    """

    def __init__(
        self, geom: ObjectGeometry, res: int, *, steps: int = 16, iterations: int = 8, backend: str = "numpy"
    ):
        self.c, self.radius, self.res = geom.center, geom.radius, res
        self.steps, self.iterations = steps, iterations
        dirs = cubemap.texel_directions(res).reshape(-1, 3)
        dist, nrm = farthest_surface(geom, dirs)
        self.texels = np.concatenate([nrm, dist[:, None]], -1).reshape(6, res, res, 4).astype(np.float32)
        self.B = backends.get(backend)
        self.env = EnvMap(self.texels, self.B)

    def exit(self, p, d):
        """Rays p + s d, p and d (N, 3) world space (d unit) → exit points e (N, 3), outward normals (N, 3)
        (float64 numpy) and ok (N,) bool: a crossing was found and the normal faces along d."""
        B, env = self.B, self.env
        x = B.vec(np.asarray(p, float) - self.c)  # ray origins relative to the centre
        dv = B.vec(np.asarray(d, float))

        def f(s):  # |l| − |l'|, l = x + s d
            l = x + dv * s
            return B.length(l) - env.distance(l)

        # ------------------------------------------------------------- linear search for the first under → over step
        zero = x.x * 0.0
        f0 = B.minimum(f(zero), -1e-7)  # the ray starts inside: under at s = 0
        s_max = 2.1 * self.radius
        br = first_crossing(B, f, zero, f0, s_max / self.steps, self.steps)

        # ------------------------------------------------------------- false position inside the bracket (eq. 3)
        br = refine(B, f, br, self.iterations, illinois=False, rising=True)
        s = secant_point(br)

        # ------------------------------------------------------------- exit point and the map's normal there
        l = x + dv * s
        r, g, b, _ = env.lookup(l)
        nl = B.length(V3(r, g, b))
        radial = B.normalize(l)
        inv = 1.0 / B.maximum(nl, 1e-12)
        has = nl > 1e-3  # the map holds a normal there
        nrm = V3(*(B.select(has, c * inv, rc) for c, rc in zip((r, g, b), (radial.x, radial.y, radial.z))))
        out = nrm.dot(dv) > 1e-6  # must face along d to refract out
        nrm = V3(
            *(B.select(out, c, rc) for c, rc in zip((nrm.x, nrm.y, nrm.z), (radial.x, radial.y, radial.z)))
        )
        ok = br.found & (nrm.dot(dv) > 0.0)
        e = B.to_numpy(l).astype(float) + self.c
        return e, B.to_numpy(nrm).astype(float), np.asarray(B.numpy(ok), bool)

    def lookups_per_ray(self) -> int:
        return 2 + self.steps + self.iterations
