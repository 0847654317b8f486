"""Caustics with caustic maps (the paper's Figure 8), and the exact photon tracing they are measured against.

Caustic map (:func:`build_caustic_map`): a view plane of ``res``² texels between the point light and the glass
sphere, its square frustum fitted to the sphere's cone (half angle asin(r / |c − light|)). Per texel:

* the light ray through the texel centre meets the sphere (else the texel is invalid: alpha = −1 in the paper);
* it is refracted in and out (:func:`study.optics.interfaces.through_sphere`, exact for a sphere);
* the photon's hit in the room is localized by a method of :mod:`study.methods` in the distance impostor, from the
  exit point x (relative to the reference point) along the exit direction R, giving the lookup vector l;
* (texture id, u, v) are read from the uv map in direction l (:class:`study.caustics.lightmap.UVMap`);
* photon power Φ = I · Δω · T: light intensity (W/sr, RGB) × the texel's exact solid angle × Fresnel
  transmittance of both interfaces.

Exact photon tracing (:func:`exact_caustic_map`): the same photons, but the exit ray is intersected with the real
room by Embree — isolating the localization error. Both feed the same splatting (:func:`study.caustics.lightmap.splat`).

Shadows: the sphere is opaque to the direct light's shadow rays — the light it intercepts is exactly what the
caustic map redistributes (minus the Fresnel-reflected part, which is dropped, as in the paper).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from study import backend as backends
from study.caustics.lightmap import UVMap
from study.errors import StudyError
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured
from study.methods import Method
from study.optics import interfaces as optics
from study.reference.embree import Tracer
from study.scene import Scene
from study.scene.objects import intersect_sphere


@dataclass
class CausticMap:
    """res × res texels, flattened to P = res²."""

    res: int
    valid: np.ndarray  # (P,) bool; the paper's alpha >= 0
    surface: np.ndarray  # (P,) int texture id (−1 invalid)
    uv: np.ndarray  # (P, 2) texture coordinates of the photon hit (NaN invalid)
    power: np.ndarray  # (P, 3) photon power, W (0 invalid)
    exit: np.ndarray  # (P, 3) exit point on the sphere, world space
    out: np.ndarray  # (P, 3) exit direction
    shown: np.ndarray  # (P, 3) photon hit estimate, world space (NaN invalid)
    seconds: dict  # phase → seconds

    @property
    def luminance(self) -> np.ndarray:
        """The paper's alpha channel: the photon's power luminance (mean of RGB), −1 where invalid."""
        return np.where(self.valid, self.power.mean(-1), -1.0)


# ---------------------------------------------------------------------------------------------- frustum
def frustum(scene: Scene, res: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Unit directions (res², 3) through the caustic-map texel centres, their exact solid angles (res²,), and the
    frustum's half-width tan(α) on the unit-distance view plane."""
    L, c, r = (
        np.asarray(scene.light.position, float),
        np.asarray(scene.object.center, float),
        scene.object.radius,
    )
    w = c - L
    D = np.linalg.norm(w)
    w /= D
    a = math.tan(math.asin(r / D))
    helper = np.array([0.0, 1.0, 0.0]) if abs(w[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(w, helper)
    right /= np.linalg.norm(right)
    up = np.cross(right, w)
    edges = np.linspace(-a, a, res + 1)
    mid = (edges[:-1] + edges[1:]) / 2
    S, T = np.meshgrid(mid, -mid)  # rows downwards
    d = w + S[..., None] * right + T[..., None] * up
    d = (d / np.linalg.norm(d, axis=-1, keepdims=True)).reshape(-1, 3)

    def F(x, y):  # solid angle of [0,x]×[0,y] at distance 1
        return np.arctan(x * y / np.sqrt(1 + x * x + y * y))

    x0, x1 = edges[None, :-1], edges[None, 1:]
    y0, y1 = edges[:-1, None], edges[1:, None]
    dw = F(x1, y1) - F(x0, y1) - F(x1, y0) + F(x0, y0)  # (res, res), symmetric in rows
    return d, dw.reshape(-1), a


def sphere_entry(scene: Scene, d: np.ndarray):
    """Light rays along d: (hit mask, entry points, outward normals)."""
    L = np.broadcast_to(np.asarray(scene.light.position, float), d.shape)
    t = intersect_sphere(L, d, scene.object.center, scene.object.radius)
    hit = np.isfinite(t)
    x = L + d * np.where(hit, t, 0.0)[:, None]
    N = (x - np.asarray(scene.object.center)) / scene.object.radius
    return hit, x, N


def _photons(scene: Scene, res: int):
    t0 = time.perf_counter()
    d, dw, _ = frustum(scene, res)
    hit, x, N = sphere_entry(scene, d)
    path = optics.through_sphere(
        x[hit], d[hit], N[hit], scene.object.center, scene.object.radius, scene.object.material.ior
    )
    P = len(d)
    exit_, out = np.full((P, 3), np.nan), np.full((P, 3), np.nan)
    T = np.zeros(P)
    exit_[hit], out[hit], T[hit] = path.exit, path.out, path.transmittance
    power = np.asarray(scene.light.intensity, float)[None, :] * (dw * T)[:, None]
    ok = hit & (T > 0)
    return ok, exit_, out, power, time.perf_counter() - t0


# ---------------------------------------------------------------------------------------------- caustic map
def build_caustic_map(
    scene: Scene, method: Method, env: Captured | EnvMap, uvmap: UVMap, *, res: int = 64
) -> CausticMap:
    """The caustic map of ``scene``'s sphere lit by its point light, photon hits localized by ``method`` in the
    views ``env`` (:class:`~study.impostor.views.Captured`, as :func:`study.measure.inputs.capture_views` makes them;
    a bare impostor: the methods' fallbacks) on their backend (which must be the backend of ``uvmap`` too).
    ``seconds`` holds the phase times."""
    if scene.object.material.type != "dielectric":
        raise StudyError("caustic maps need a dielectric object", key="object.material")
    B = env.B
    o = np.asarray(scene.reference.point, float)
    ok, exit_, out, power, t_refr = _photons(scene, res)
    # ------------------------------------------------------------------ localization and uv lookup (backend)
    t0 = time.perf_counter()
    xs, Rs = np.nan_to_num(exit_[ok] - o), np.nan_to_num(out[ok])
    x, R = B.vec(xs), B.vec(Rs)
    loc = method.localize(B, env, x, R)
    sid, u, v = uvmap.lookup(loc.l)
    B.eval(sid, u, v, loc.valid)
    sid, u, v = B.numpy(sid), B.numpy(u), B.numpy(v)
    lvalid = B.numpy(loc.valid).astype(bool)
    t_loc = time.perf_counter() - t0
    # ------------------------------------------------------------------ shown points (diagnostics, not timed)
    lnp = B.to_numpy(loc.l).astype(np.float64)
    dist = np.asarray(env.B.numpy(env.distance(loc.l)), float)
    shown_ok = lnp / np.linalg.norm(lnp, axis=-1, keepdims=True) * dist[:, None] + o
    # ------------------------------------------------------------------ assemble
    P = res * res
    valid = ok.copy()
    valid[ok] = lvalid & (sid >= -0.5)
    surface = np.full(P, -1, np.int64)
    uv = np.full((P, 2), np.nan)
    shown = np.full((P, 3), np.nan)
    surface[ok] = np.rint(sid).astype(np.int64)
    uv[ok] = np.stack([u, v], -1)
    shown[ok] = shown_ok
    surface[~valid] = -1
    uv[~valid] = np.nan
    power = np.where(valid[:, None], power, 0.0)
    return CausticMap(
        res,
        valid,
        surface,
        uv,
        power,
        exit_,
        out,
        shown,
        {"refract": t_refr, "localize": t_loc, "total": t_refr + t_loc},
    )


def exact_caustic_map(scene: Scene, tracer: Tracer, *, res: int = 64) -> CausticMap:
    """Reference (a): the same photons, hits found by Embree in the real room."""
    ok, exit_, out, power, t_refr = _photons(scene, res)
    t0 = time.perf_counter()
    hit = tracer.intersect(np.nan_to_num(exit_[ok]), np.nan_to_num(out[ok]))
    P = res * res
    valid = ok.copy()
    valid[ok] = hit["surface"] >= 0
    surface = np.full(P, -1, np.int64)
    uv = np.full((P, 2), np.nan)
    shown = np.full((P, 3), np.nan)
    surface[ok], uv[ok], shown[ok] = hit["surface"], hit["uv"], hit["point"]
    power = np.where(valid[:, None], power, 0.0)
    return CausticMap(
        res,
        valid,
        surface,
        uv,
        power,
        exit_,
        out,
        shown,
        {"refract": t_refr, "localize": time.perf_counter() - t0},
    )


def time_caustic_map(
    scene: Scene, method: Method, env: Captured | EnvMap, uvmap: UVMap, *, res: int, repeats: int = 5
) -> float:
    """Median seconds to build one caustic map (after one warm-up build, which also traces Dr.Jit kernels)."""
    build_caustic_map(scene, method, env, uvmap, res=res)
    ts = [build_caustic_map(scene, method, env, uvmap, res=res).seconds["total"] for _ in range(repeats)]
    return float(np.median(ts))


def cone_power(scene: Scene, n: int = 20000) -> np.ndarray:
    """Independent check: ∫ over the sphere's cone of I · T(θ) dω by quadrature in the off-axis angle θ (RGB W)."""
    L, c, r = (
        np.asarray(scene.light.position, float),
        np.asarray(scene.object.center, float),
        scene.object.radius,
    )
    D = np.linalg.norm(c - L)
    half_angle = math.asin(r / D)  # of the cone of light rays that meet the sphere
    th = (np.arange(n) + 0.5) / n * half_angle
    sin_i = np.clip(D * np.sin(th) / r, 0, 1)  # incidence angle at the sphere
    cos_i = np.sqrt(1 - sin_i**2)
    eta = 1 / scene.object.material.ior
    F_in = optics.fresnel_dielectric(cos_i, eta)
    cos_t = np.sqrt(1 - (eta * sin_i) ** 2)
    F_out = optics.fresnel_dielectric(cos_t, 1 / eta)
    integrand = (1 - F_in) * (1 - F_out) * 2 * np.pi * np.sin(th)
    return np.asarray(scene.light.intensity, float) * integrand.sum() * half_angle / n


__all__ = [
    "CausticMap",
    "build_caustic_map",
    "exact_caustic_map",
    "frustum",
    "cone_power",
    "time_caustic_map",
    "backends",
]
