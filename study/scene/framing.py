"""What a camera shows, in numbers, by casting rays through its pixels against the environment's triangles
(Embree, :func:`study.scene.placement.cast`) and the object's bounding sphere: the numbers automatic placement
scores its candidates by (:mod:`study.scene.autoplace`) and the tests hold the chosen view to.

=================  ==============================================================================================
``object``         share of the pixels whose primary ray meets the object's bounding sphere first
``void``           share of the pixels whose primary ray misses the object and leaves the scene (sees the sky)
``mirrored_void``  share of the object's pixels whose ray, reflected off the bounding sphere, leaves the scene:
                   how much of the object's mirror image is sky rather than the environment
=================  ==============================================================================================
"""

from __future__ import annotations

import numpy as np

import study.scene.placement as placement


def pixel_rays(eye, target, up, fov: float, width: int, height: int, n: int = 32) -> np.ndarray:
    """(N, 3) unit directions through an n-wide grid of pixel centres of a pinhole camera (horizontal ``fov``,
    degrees), as Mitsuba's ``perspective`` sensor with ``fov_axis = "x"`` spans them."""
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    rows = max(1, round(n * height / width))
    tx = np.tan(np.radians(fov) / 2)
    ty = tx * height / width
    sx = ((np.arange(n) + 0.5) / n * 2 - 1) * tx
    sy = (1 - (np.arange(rows) + 0.5) / rows * 2) * ty
    X, Y = np.meshgrid(sx, sy)
    d = f + X[..., None] * r + Y[..., None] * u
    d = d.reshape(-1, 3)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def sphere_hit(eye, d: np.ndarray, centre, radius: float) -> np.ndarray:
    """Distance along each ray (eye, d) to the sphere's near side, inf where it misses."""
    oc = np.asarray(eye, float) - np.asarray(centre, float)
    b = d @ oc
    disc = b * b - (oc @ oc - radius * radius)
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    return np.where((disc > 0) & (t > 0), t, np.inf)


def numbers(mesh, eye, target, up, fov: float, width: int, height: int, centre, radius: float, n: int = 32):
    """``{"object", "void", "mirrored_void"}`` (module docstring) of the view from ``eye`` towards ``target``,
    with ``n`` pixel columns."""
    eye = np.asarray(eye, float)
    d = pixel_rays(eye, target, up, fov, width, height, n)
    t_env, _ = placement.cast(mesh, np.broadcast_to(eye, d.shape), d)
    t_obj = sphere_hit(eye, d, centre, radius)
    on = t_obj < t_env
    void = ~on & ~np.isfinite(t_env)
    mirrored = 0.0
    if on.any():
        p = eye + d[on] * t_obj[on, None]
        nrm = (p - np.asarray(centre, float)) / radius
        refl = d[on] - 2 * np.sum(d[on] * nrm, -1, keepdims=True) * nrm
        t_ref, _ = placement.cast(mesh, p + nrm * 1e-4 * radius, refl)
        mirrored = float(np.mean(~np.isfinite(t_ref)))
    return {"object": float(on.mean()), "void": float(void.mean()), "mirrored_void": mirrored}
