"""Several distance cube maps at different points (light-field probes, McGuire et al. 2017, with radiance and radial
distance only): where they stand, their capture, and :class:`ProbeSet`, all of them bound to one backend.

Probe 0 is the reference point's own impostor; probes 1 … N−1 stand at :func:`probe_points`. Each is an ordinary
distance impostor (:mod:`study.impostor.capture`) taken from its own centre c_k: radiance by Mitsuba
(:func:`~study.impostor.capture.render_cube` from c_k, cached under the same key an impostor taken there would
have), distances |p − c_k| by Embree through its texel centres (:func:`~study.impostor.capture.distances_from`).
The N maps share one resolution and are stacked into one (6N, R, R, C) texture, so a lookup into the probe k of
each ray (k an (N,) array) costs one fetch whatever N is: face index 6k + face.
"""

from __future__ import annotations

import numpy as np

from study import progress
from study.backend import V3, Backend
from study.cache import Cache, content_key
from study.impostor import cubemap
from study.impostor.capture import distances_from, impostor_key, render_cube
from study.impostor.pyramid import MinPyramid
from study.impostor.views import ProbeSpec
from study.reference.embree import Tracer
from study.scene import Scene, placement
from study.scene.environment import env_key
from study.validation import KeyedError


def probe_points(spec: ProbeSpec, bounds, tracer: Tracer) -> np.ndarray:
    """World positions of the probes of ``spec`` besides the reference point: (M, 3) float64.

    ``spec.points`` as given; else the centres of a ``spec.grid`` of equal cells in ``bounds`` = (min, max), less
    those a reference point could not stand at (:func:`study.scene.placement.check_free`: inside a solid, or not
    enclosed by surfaces) or closer than ``spec.clearance`` to a surface."""
    if spec.points is not None:
        return np.asarray(spec.points, float).reshape(-1, 3)
    lo, hi = (np.asarray(b, float) for b in bounds)
    axes = [lo[i] + (np.arange(n) + 0.5) * (hi[i] - lo[i]) / n for i, n in enumerate(spec.grid)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    keep = []
    for p in pts:
        try:
            placement.check_free(tracer.mesh, p, "probe", enclosed=True)
            keep.append(placement.clearance(tracer.mesh, p) >= spec.clearance)
        except KeyedError:
            keep.append(False)
    return pts[np.asarray(keep, bool)]


def probe_texels(tracer: Tracer, point, res: int, radiance, dist: np.ndarray | None = None) -> np.ndarray:
    """One probe's texels (6, R, R, 4): RGB = ``radiance`` (a (6, R, R, 3) array, or a function of the (6·R·R, 3)
    texel-centre surface points), distance from ``point`` (``dist`` when given, else traced by ``tracer``)."""
    if dist is None:
        dist = distances_from(tracer, point, res, key="method.points")  # FAR where a texel ray escapes
    dist = np.asarray(dist, np.float32).reshape(6, res, res)
    if callable(radiance):
        pts = np.asarray(point, float) + cubemap.texel_directions(res).reshape(-1, 3) * dist.reshape(-1, 1)
        radiance = radiance(pts)
    rgb = np.asarray(radiance, np.float32).reshape(6, res, res, 3)
    return np.concatenate([rgb, dist[..., None]], -1).astype(np.float32)


def probe_distance_key(at: Scene) -> str:
    """Content key of a probe's distances (``at``: the scene with the probe's centre as its reference point): the
    environment's triangles, the centre and the cube resolution, nothing path traced (Embree's exact distances,
    :func:`~study.impostor.capture.distances_from`): not the seed, the samples, the bounces or the light, so the
    seeds of one geometry read one capture (their radiance, path traced, is drawn per seed)."""
    return content_key(
        env_key(at), [float(c) for c in at.reference.point], at.render.cube_res, "probe-distance-v1"
    )


def capture_probes(
    scene: Scene, spec: ProbeSpec, cache: Cache, texels0: np.ndarray, tracer: Tracer, bounds=None
) -> tuple[np.ndarray, np.ndarray]:
    """Texels (N, 6, R, R, 4) and world centres (N, 3) of the probe set ``spec`` of ``scene``: probe 0 the
    reference impostor (``texels0``), then one probe per :func:`probe_points` (``bounds``: the environment's),
    its radiance rendered by Mitsuba from there (``render.probe_spp`` samples per texel, by default ``cube_spp``) and
    its distances traced, both cached like an impostor taken there."""
    r = scene.render
    spp = r.probe_spp or r.cube_spp  # the probes' own sample count (render.probe_spp), else the impostor's
    pts = probe_points(spec, bounds if bounds is not None else scene.bounds(), tracer)
    maps, centres = [np.asarray(texels0, np.float32)], [np.asarray(scene.reference.point, float)]
    loaded: dict = {}  # one Mitsuba scene for every probe: they differ in the reference point alone
    for i, p in enumerate(pts):
        progress.note(
            f"probe {i + 1}/{len(pts)}: its cube map, path traced"
        )  # long: the stage's lines say so
        at = scene.with_updates({"reference.point": [float(c) for c in p]}, frame="measured")
        rad = cache.get(
            "radiance",
            impostor_key(at, spp=spp),
            lambda at=at: render_cube(at, r.cube_res, spp, loaded),
            code=render_cube,
        )
        dist = cache.get(
            "distance",
            probe_distance_key(at),
            lambda p=p: distances_from(tracer, p, r.cube_res, key="method.points"),
            code=distances_from,
        )
        maps.append(probe_texels(tracer, p, r.cube_res, rad, dist))
        centres.append(p)
    return np.stack(maps), np.stack(centres)


class ProbeSet:
    """N distance cube maps (:mod:`study.impostor.cubemap` convention) stacked for one backend.

    ``centres`` (N, 3): the probes' centres relative to the reference point o (probe 0 at o, numpy float64).
    ``distance(k, v)`` / ``lookup(k, v)``: the stored distance (RGB and distance) of probe k (a per-ray float array
    of probe indices) in direction v from that probe's centre; ``nearest(k, v)`` the distance of the texel whose
    centre is nearest to v (no interpolation: what the probe saw through one texel). ``res`` texels per face edge."""

    def __init__(self, texels: np.ndarray, centres: np.ndarray, B: Backend):
        n, six, res = texels.shape[:3]
        self.B, self.n, self.res = B, n, res
        self.centres = np.asarray(centres, float).reshape(n, 3)
        flat = texels.reshape(n * six, res, res, texels.shape[-1])
        self.tex = B.texture(flat[..., :-1])
        self.dist = B.texture(flat[..., -1:])
        self._dist_np, self._pyramid = flat[..., -1], None

    @property
    def pyramid(self) -> MinPyramid:
        """The min pyramid of the 6N faces' distances (probe k's face f is face 6k + f), built on first use and
        kept, as :attr:`study.impostor.envmap.EnvMap.pyramid`."""
        if self._pyramid is None:
            self._pyramid = MinPyramid(self._dist_np, self.B)
        return self._pyramid

    @classmethod
    def around(cls, texels: np.ndarray, centres_world: np.ndarray, reference, B: Backend) -> ProbeSet:
        """From world centres (probe 0 at ``reference``)."""
        return cls(texels, np.asarray(centres_world, float) - np.asarray(reference, float), B)

    def _face(self, k, v: V3):
        face, u, w = cubemap.face_uv(self.B, v.x, v.y, v.z)
        return face + 6.0 * k, u, w

    def distance(self, k, v: V3):
        return self.B.sample(self.dist, *self._face(k, v))[0]

    def lookup(self, k, v: V3) -> list:
        f = self._face(k, v)
        return self.B.sample(self.tex, *f) + self.B.sample(self.dist, *f)

    def nearest(self, k, v: V3):
        B, R = self.B, float(self.res)
        face, u, w = self._face(k, v)
        uc = (B.minimum(B.floor(u * R), R - 1.0) + 0.5) / R  # the texel centre nearest to (u, w)
        wc = (B.minimum(B.floor(w * R), R - 1.0) + 0.5) / R
        return B.sample(self.dist, face, uc, wc)[0]

    def centre(self, k) -> V3:
        """Centre of probe k per ray (relative to o)."""
        B = self.B
        c = [k * 0.0 + float(a) for a in self.centres[-1]]
        for i in range(self.n - 2, -1, -1):
            c = [B.select(k == float(i), k * 0.0 + float(a), b) for a, b in zip(self.centres[i], c)]
        return V3(*c)
