"""Temporal error of a frame sequence along the renderer's exact motion: E_warp (Lai et al. 2018, "Learning Blind
Video Temporal Consistency", there with optical flow), the previous frame warped onto the current one along the
exact flow, masked where the point was not seen. Torch-free: the motion figure measures it beside ColorVideoVDP
(:mod:`study.measure.video`), and where that is not installed.

The flow is exact because the motion is known: the environment stands still and the object translates from one
frame's ``object.center`` to the next (the camera may move too). Through each pixel centre of the current frame the
camera ray's first hit X is found (Embree for the environment, the object's own intersection); the same material
point was at X − Δc on the object (Δc the centre's step) or at X in the environment, and the previous camera
projects it to continuous pixel coordinates. It counts as seen there (``Flow.valid``) where

- the previous frame's first hit along the ray from its eye to that point is the point itself (nothing of the
  environment or of the object in front of it: a background pixel the object covered a frame earlier is
  disoccluded and left out), and
- every pixel the bilinear lookup reads holds one surface in both frames, the same as the current pixel: fully on
  the object, or fully off it (no sub-pixel ray on it; pixels the silhouette crosses are mixed and left out).

E_warp of one step: over the pixels both seen and on the object in the current frame (``region``, default), the
mean of ‖I_t − Ŵ(I_{t−1})‖² over the sRGB channels in [0, 1] (Lai's L2) and the mean LDR-FLIP of Ŵ(I_{t−1})
against I_t (:func:`study.measure.metrics.flip_map`). The warp interpolates the linear radiance bilinearly; a
frame warped onto itself with no motion reads every pixel back exactly (E_warp 0). A sequence's value is the mean
over its steps. It counts every change along the motion, wanted or not: the truth's own (``truth_at_hit``) holds
the reflection's true slide over the moving object and its Monte Carlo noise, drawn anew each frame. A method far
above it flickers (hits that jump between frames); one below it changes less than the truth does — steadier, not
closer (a reflection that lags the motion, as environment mapping's, is steady too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from study.errors import StudyError
from study.measure.metrics import flip_map, to_ldr
from study.scene import Scene, camera_rays, look_at_basis, objects

#: the depth test's tolerance (relative, absolute in metres), as the exact hits' occlusion test in run_case
WARP_REL_EPS, WARP_ABS_EPS = 1e-4, 1e-5
#: surface classes of a pixel (``Flow.surface``)
ENV_SURFACE, OBJECT, MIXED = 0, 1, -1


@dataclass(frozen=True)
class Flow:
    """Where each pixel of the current frame was in the previous one."""

    coords: np.ndarray  # (H, W, 2) float: (row, column) in the previous frame, pixel centres at integers
    valid: np.ndarray  # (H, W) bool: the point was seen there (module docstring)
    surface: np.ndarray  # (H, W) int8: the current pixel's surface: OBJECT, ENV_SURFACE or MIXED


def project(cam, points: np.ndarray, *, at_infinity: np.ndarray | None = None) -> np.ndarray:
    """(N, 2) continuous (row, column) of world points through camera ``cam`` (pixel centres at integers), the
    inverse of :func:`study.scene.camera_rays`; ``at_infinity`` (N,) marks points given as directions. NaN
    behind the eye."""
    f, r, u = look_at_basis(cam.eye, cam.target, cam.up)
    v = np.asarray(points, float) - np.asarray(cam.eye, float)
    if at_infinity is not None:
        v = np.where(at_infinity[:, None], points, v)
    z = v @ f
    with np.errstate(divide="ignore", invalid="ignore"):
        xs, ys = np.where(z > 0, (v @ r) / z, np.nan), np.where(z > 0, (v @ u) / z, np.nan)
    tan = math.tan(math.radians(cam.fov) / 2)
    W, H = cam.width, cam.height
    return np.stack([(1 - ys / (tan * H / W)) * H / 2 - 0.5, (xs / tan + 1) * W / 2 - 0.5], -1)


def _first_hits(scene: Scene, tracer, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(environment distance, object distance) of rays o + t d (unit d), inf on a miss."""
    t_env = np.asarray(tracer.distance(o, d), float)
    t_obj, _ = objects.object_geometry(scene).intersect(o, d)
    return t_env, np.where(np.isfinite(t_obj), t_obj, np.inf)


def surfaces(scene: Scene, tracer) -> np.ndarray:
    """(H, W) int8: OBJECT where every sub-pixel ray (``render.supersample``²) first meets the object,
    ENV_SURFACE where none does, MIXED between."""
    o, d = camera_rays(scene.camera, scene.render.supersample)
    H, W, S, _ = d.shape
    t_env, t_obj = _first_hits(scene, tracer, o.reshape(-1, 3), d.reshape(-1, 3))
    on = (t_obj < t_env).reshape(H, W, S)
    return np.where(on.all(-1), OBJECT, np.where(on.any(-1), MIXED, ENV_SURFACE)).astype(np.int8)


def exact_flow(
    prev: Scene,
    cur: Scene,
    tracer,
    *,
    prev_surface: np.ndarray | None = None,
    surface: np.ndarray | None = None,
) -> Flow:
    """The exact flow from frame ``prev`` to frame ``cur`` (module docstring); ``tracer``: the environment's
    (:func:`study.reference.tracer.make_tracer`); the frames' :func:`surfaces`, when already computed."""
    _same_but_motion(prev, cur)
    prev_surface = surfaces(prev, tracer) if prev_surface is None else prev_surface
    surface = surfaces(cur, tracer) if surface is None else surface
    o, d = camera_rays(cur.camera, 1)
    H, W = d.shape[:2]
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    t_env, t_obj = _first_hits(cur, tracer, o, d)
    on = t_obj < t_env
    t = np.minimum(t_env, t_obj)
    far = ~np.isfinite(t)  # the ray leaves the scene: a direction, still in every frame
    x = np.where(far[:, None], d, o + d * np.where(far, 0.0, t)[:, None])
    x = x - on[:, None] * (np.subtract(cur.object.center, prev.object.center))[None, :]  # where it was
    coords = project(prev.camera, x, at_infinity=far)
    eye = np.broadcast_to(np.asarray(prev.camera.eye, float), x.shape)  # seen from the previous eye?
    to = np.where(far[:, None], x, x - eye)
    dist = np.where(far, np.inf, np.linalg.norm(to, axis=-1))
    dirs = to / np.where(far, 1.0, dist)[:, None]
    p_env, p_obj = _first_hits(prev, tracer, eye, dirs)
    first = np.minimum(p_env, p_obj)
    seen = np.where(far, ~np.isfinite(first), first >= dist * (1 - WARP_REL_EPS) - WARP_ABS_EPS)
    seen &= np.where(on, p_obj <= p_env, True)  # an object point is seen on the object, not through it
    coords = coords.reshape(H, W, 2)
    valid = seen.reshape(H, W) & (surface != MIXED) & _same_surface(coords, prev_surface, surface)
    return Flow(coords, valid, surface)


def _same_but_motion(prev: Scene, cur: Scene) -> None:
    """Refuse two frames that differ in more than the object's centre and the camera (the flow would be wrong)."""
    a, b = prev.model_dump(), cur.model_dump()
    for s in (a, b):
        s.pop("camera", None)
        s.get("object", {}).pop("center", None)
    if a != b:
        keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        raise StudyError(
            "the exact flow needs frames that differ only in object.center and the camera; these differ in "
            + ", ".join(keys),
            key=keys[0],
        )


def _corners(coords: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bilinear lookup at ``coords`` (..., 2): the top-left pixel (i0, j0) and the weights (wi, wj) of the next
    row and column; coordinates within 1e-6 of a pixel centre are snapped to it."""
    c = np.where(np.abs(coords - np.round(coords)) < 1e-6, np.round(coords), coords)
    c = np.nan_to_num(c, nan=-2.0)
    i0, j0 = np.floor(c[..., 0]).astype(int), np.floor(c[..., 1]).astype(int)
    return i0, j0, c[..., 0] - i0, c[..., 1] - j0


def _same_surface(coords: np.ndarray, prev_surface: np.ndarray, surface: np.ndarray) -> np.ndarray:
    """Every pixel the bilinear lookup reads (weight > 0) lies in the frame and has the current pixel's surface."""
    H, W = prev_surface.shape
    i0, j0, wi, wj = _corners(coords)
    ok = np.ones(i0.shape, bool)
    for di, dj, w in ((0, 0, 1.0), (1, 0, wi), (0, 1, wj), (1, 1, wi * wj)):
        i, j = i0 + di, j0 + dj
        inside = (i >= 0) & (i < H) & (j >= 0) & (j < W)
        read = (w > 0) if di or dj else np.ones_like(ok)
        same = inside & (prev_surface[np.clip(i, 0, H - 1), np.clip(j, 0, W - 1)] == surface)
        ok &= ~read | same
    return ok


def warp(image: np.ndarray, coords: np.ndarray) -> np.ndarray:
    """``image`` (H, W, C) read at ``coords`` (H, W, 2) bilinearly (edges clamped): the previous frame brought
    onto the current one."""
    H, W = image.shape[:2]
    i0, j0, wi, wj = _corners(coords)
    img = np.asarray(image, np.float64)

    def at(i, j):
        return img[np.clip(i, 0, H - 1), np.clip(j, 0, W - 1)]

    wi, wj = wi[..., None], wj[..., None]
    top = at(i0, j0) * (1 - wj) + at(i0, j0 + 1) * wj
    bottom = at(i0 + 1, j0) * (1 - wj) + at(i0 + 1, j0 + 1) * wj
    return top * (1 - wi) + bottom * wi


def ewarp(prev: np.ndarray, cur: np.ndarray, flow: Flow, *, region: np.ndarray | None = None) -> dict:
    """E_warp of one step (module docstring) between linear-radiance frames (H, W, 3): ``ewarp_l2``,
    ``ewarp_flip`` (NaN where no pixel counts) and ``ewarp_pixels``, the pixels counted. ``region``: the pixels
    to count (default: on the object in the current frame), always within ``flow.valid``."""
    m = flow.valid & (flow.surface == OBJECT if region is None else np.asarray(region, bool))
    if not m.any():
        return {"ewarp_l2": np.nan, "ewarp_flip": np.nan, "ewarp_pixels": 0}
    cur = np.asarray(cur, np.float64)
    warped = np.where(m[..., None], warp(prev, flow.coords), cur)  # pixels not counted: no difference
    d = to_ldr(cur[m]) - to_ldr(warped[m])
    fmap = flip_map(cur, warped)
    return {
        "ewarp_l2": float(np.mean(np.sum(d * d, axis=-1))),
        "ewarp_flip": float(np.mean(fmap[m])),
        "ewarp_pixels": int(m.sum()),
    }


def sequence_flows(scenes: list[Scene], tracer=None) -> list[Flow]:
    """The exact flows of a sequence of frames: flows[k] brings frame k onto frame k + 1. ``tracer``: the
    environment's (default: made from the first frame's)."""
    if tracer is None:
        from study.reference.tracer import make_tracer

        tracer = make_tracer(scenes[0].mesh())
    surf = [surfaces(s, tracer) for s in scenes]
    return [
        exact_flow(a, b, tracer, prev_surface=sa, surface=sb)
        for a, b, sa, sb in zip(scenes[:-1], scenes[1:], surf[:-1], surf[1:])
    ]


def sequence_ewarp(frames: list[np.ndarray], flows: list[Flow]) -> tuple[dict, list[dict]]:
    """(E_warp of the sequence: the means over its steps, per step's values) of linear frames along ``flows``."""
    steps = [ewarp(a, b, f) for a, b, f in zip(frames[:-1], frames[1:], flows)]

    def mean(k):
        v = np.array([s[k] for s in steps], float)
        return float(np.nanmean(v)) if np.isfinite(v).any() else np.nan

    return {"ewarp_l2": mean("ewarp_l2"), "ewarp_flip": mean("ewarp_flip")}, steps
