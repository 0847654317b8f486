"""Geometric optics shared by refraction and caustics: Snell's law, dielectric Fresnel, the two-interface path
through a sphere. numpy, (N, 3) row vectors, unit directions; ``eta`` is always n_from / n_to (the index of the
medium the ray comes from over that of the medium it enters).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from study.scene.objects import sphere_exit


def refract(d: np.ndarray, n: np.ndarray, eta) -> tuple[np.ndarray, np.ndarray]:
    """Refract unit directions ``d`` at unit normals ``n`` facing against ``d`` (d·n < 0), eta = n_from/n_to.

    Returns (t, ok): t (N, 3) unit refracted directions (NaN where total internal reflection), ok (N,) bool."""
    eta = float(eta)
    cos_i = -np.sum(d * n, axis=-1)
    k = 1 - eta**2 * (1 - cos_i**2)
    ok = k >= 0
    with np.errstate(invalid="ignore"):
        t = eta * d + (eta * cos_i - np.sqrt(np.where(ok, k, np.nan)))[:, None] * n
    return t, ok


def fresnel_dielectric(cos_i: np.ndarray, eta) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance for light arriving with cos_i (> 0) from the side of index n_from,
    eta = n_from/n_to. 1 under total internal reflection. (As Mitsuba's ``fresnel`` with eta = n_to/n_from.)"""
    cos_i = np.clip(np.asarray(cos_i, float), 0, 1)
    sin_t2 = eta**2 * (1 - cos_i**2)
    tir = sin_t2 >= 1
    cos_t = np.sqrt(np.clip(1 - sin_t2, 0, 1))
    with np.errstate(invalid="ignore", divide="ignore"):  # 0/0 only at grazing TIR, replaced below
        rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    return np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    return d - 2 * np.sum(d * n, axis=-1, keepdims=True) * n


@dataclass
class SpherePath:
    """Two-interface path of rays entering a dielectric sphere (index ``ior``, outside 1)."""

    inner: np.ndarray  # (N, 3) direction inside the sphere
    exit: np.ndarray  # (N, 3) exit point on the sphere
    out: np.ndarray  # (N, 3) direction leaving the sphere (NaN where TIR at the exit)
    transmittance: np.ndarray  # (N,) (1 − F_in)(1 − F_out), 0 under TIR
    ok: np.ndarray  # (N,) bool, False where total internal reflection at the exit


def through_sphere(x: np.ndarray, d: np.ndarray, N: np.ndarray, center, radius, ior: float) -> SpherePath:
    """Refract rays arriving at entry points ``x`` (outward normals ``N``) into the sphere and out again.

    Inside a sphere the exit angle equals the entry angle, so TIR at the exit cannot happen for light entering
    from outside; ``ok`` is still computed, for meshes and for round-off."""
    inner, _ = refract(d, N, 1.0 / ior)
    F_in = fresnel_dielectric(-np.sum(d * N, axis=-1), 1.0 / ior)
    e = sphere_exit(x, inner, center, radius)
    Ne = (e - np.asarray(center, float)) / radius
    out, ok = refract(inner, -Ne, ior)
    F_out = fresnel_dielectric(np.sum(inner * Ne, axis=-1), ior)
    return SpherePath(inner, e, out, np.where(ok, (1 - F_in) * (1 - F_out), 0.0), ok)


# ---------------------------------------------------------------------------------------------- general objects
@dataclass
class DielectricPath:
    """Rays entering a dielectric object, followed to where they leave it (after total internal reflections)."""

    origin: np.ndarray  # (N, 3) where the ray leaves the object (NaN where dropped)
    out: np.ndarray  # (N, 3) unit direction leaving the object (NaN where dropped)
    transmittance: np.ndarray  # (N,) (1 − F_in)(1 − F_out), 0 where dropped
    bounces: np.ndarray  # (N,) total internal reflections on the way
    ok: np.ndarray  # (N,) bool: left the object within the bounce budget and every exit was found


def through_object(
    x: np.ndarray, d: np.ndarray, N: np.ndarray, ior: float, exit_fn, *, max_bounces: int = 4
) -> DielectricPath:
    """Refract rays (unit ``d``) into an object at entry points ``x`` with outward normals ``N``, and out again.

    ``exit_fn(p, d) -> (e, n, found)`` gives where rays from p inside the object leave it, the outward normal there
    and whether an exit was found (a sphere's closed form, Embree on a mesh, or the object's distance map). At an
    exit under total internal reflection the ray reflects inside and goes on, at most ``max_bounces`` times; rays
    still inside then (or whose exit was not found) are dropped: ``ok`` False, NaN origin and direction. The part
    F_out reflected back inside at a transmitting exit is not followed (its energy is lost, a few per cent)."""
    n = len(x)
    inner, _ = refract(d, N, 1.0 / ior)
    T = 1 - fresnel_dielectric(-np.sum(d * N, axis=-1), 1.0 / ior)
    origin, out = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    trans, bounces = np.zeros(n), np.zeros(n, int)
    done, ok = np.zeros(n, bool), np.zeros(n, bool)
    p, dd = np.asarray(x, float).copy(), inner
    for _ in range(max_bounces + 1):
        live = np.nonzero(~done)[0]
        if live.size == 0:
            break
        e, ne, found = exit_fn(p[live], dd[live])
        t_out, can = refract(dd[live], -ne, ior)
        F_out = fresnel_dielectric(np.sum(dd[live] * ne, axis=-1), ior)
        leave = found & can
        idx = live[leave]
        origin[idx], out[idx], trans[idx], ok[idx] = (
            e[leave],
            t_out[leave],
            (T[idx] * (1 - F_out[leave])),
            True,
        )
        done[idx] = True
        done[live[~found]] = True  # lost: no exit found
        tir = found & ~can
        p[live[tir]] = e[tir]
        dd[live[tir]] = reflect(dd[live][tir], -ne[tir])
        bounces[live[tir]] += 1
    return DielectricPath(origin, out, trans, bounces, ok)
