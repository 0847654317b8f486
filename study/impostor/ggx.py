"""The GGX lobe of a rough surface (Walter et al. 2007), as Mitsuba's ``roughconductor`` has it: the normal
distribution D, Smith's separable masking-shadowing G = G₁(v) G₁(l), importance sampling of half vectors, the
directional albedo E and the lobe's dominant direction.

Symbols: n the shading normal, v the direction towards the eye, l towards the light (the environment), h the
half vector (v + l)/|v + l|, α the isotropic roughness (0: a mirror). Sampling h with density D(h)(n·h) gives
l = 2(v·h)h − v with density D(h)(n·h)/(4 v·h), so the BRDF f = F D G / (4 (n·v)(n·l)) times (n·l) over that
density is the weight w = F(v·h) G (v·h) / ((n·h)(n·v)) (0 where n·l ≤ 0).

Half vectors in the local frame depend on α and the two uniform numbers only, so they are made on the host
(numpy); :func:`lobe_directions` turns them into world directions with backend operations only (arithmetic,
``sqrt``, ``select``), so the stochastic method runs on every backend.
"""

from __future__ import annotations

import numpy as np

from study.backend import V3, Backend


# ---------------------------------------------------------------------------------------------- the lobe
def ndf(cos_h, alpha: float):
    """D(h) for cos θ_h = n·h (numpy): α² / (π (cos²θ_h (α² − 1) + 1)²)."""
    a2 = alpha * alpha
    c2 = np.asarray(cos_h, float) ** 2
    return a2 / (np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2)


def smith_g1(cos, alpha: float, sqrt=np.sqrt):
    """Smith's G₁ of GGX for cos θ = n·w > 0: 2 cos / (cos + √(α² + (1 − α²) cos²)); ``sqrt`` of the backend."""
    a2 = alpha * alpha
    return 2.0 * cos / (cos + sqrt(cos * cos * (1.0 - a2) + a2))


def half_vectors(alpha: float, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Half vectors (…, 3) in the local frame (z = n) sampled with density D(h)(n·h) from uniform u1, u2."""
    cos_t = np.sqrt((1.0 - u1) / (1.0 + (alpha * alpha - 1.0) * u1))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u2
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], -1)


def hammersley(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n points of the Hammersley set in [0, 1)²: (i + ½)/n and the radical inverse of i in base 2."""
    i = np.arange(n, dtype=np.uint64)
    rev = np.zeros(n, dtype=np.float64)
    f, k = 0.5, i.copy()
    while k.any():
        rev += f * (k & 1)
        k >>= np.uint64(1)
        f *= 0.5
    return (np.arange(n) + 0.5) / n, rev


def frame(B: Backend, n: V3) -> tuple[V3, V3]:
    """Two unit tangents completing n to an orthonormal frame, branch-free (Duff et al. 2017)."""
    one = n.z * 0.0 + 1.0
    s = B.select(n.z >= 0.0, one, -one)
    a = -1.0 / (s + n.z)
    b = n.x * n.y * a
    t = V3(1.0 + s * n.x * n.x * a, s * b, -s * n.x)
    bt = V3(b, s + n.y * n.y * a, -n.y)
    return t, bt


def lobe_directions(B: Backend, n: V3, v: V3, h_local, alpha: float) -> tuple[V3, object]:
    """One sample per ray: the direction l and the weight w = G (v·h)/((n·h)(n·v)) (no Fresnel; 0 below the
    surface). ``h_local``: three arrays (or numbers) of local half-vector coordinates."""
    t, bt = frame(B, n)
    hx, hy, hz = h_local
    h = V3(t.x * hx + bt.x * hy + n.x * hz, t.y * hx + bt.y * hy + n.y * hz, t.z * hx + bt.z * hy + n.z * hz)
    vh = v.dot(h)
    l = h * (2.0 * vh) - v
    nl, nv, nh = n.dot(l), B.maximum(n.dot(v), 1e-6), B.maximum(n.dot(h), 1e-6)
    g = smith_g1(nv, alpha, B.sqrt) * smith_g1(B.maximum(nl, 1e-6), alpha, B.sqrt)
    w = B.select((nl > 0.0) & (vh > 0.0), g * vh / (nh * nv), nl * 0.0)
    return l, w


def lobe_samples(B: Backend, n: V3, v: V3, alpha: float, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K directions per shading point importance-sampled from its GGX lobe, ``u`` (K, 2, M) uniforms:
    ((K·M, 3) unit directions, float64, sample k of every point before sample k + 1; (K, M, 1) their weights
    G (v·h)/((n·h)(n·v)), 0 below the surface): the glossy truth's and traced_glossy's estimator."""
    dirs, w = [], []
    for k in range(len(u)):
        h = half_vectors(alpha, u[k, 0], u[k, 1])
        l, wk = lobe_directions(B, n, v, (h[:, 0], h[:, 1], h[:, 2]), alpha)
        dirs.append(B.to_numpy(l).astype(np.float64))
        w.append(np.asarray(wk, np.float64))
    d = np.concatenate(dirs)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return d, np.stack(w)[..., None]


def dominant_direction(B: Backend, n: V3, R: V3, alpha: float) -> V3:
    """The direction where the GGX lobe of mirror direction R peaks, lerp(n, R, s) normalized with
    s = (1 − α)(√(1 − α) + α) (Lagarde and de Rousiers 2014, Frostbite); R itself at α = 0."""
    s = (1.0 - alpha) * (np.sqrt(1.0 - alpha) + alpha)
    return B.normalize(n * (1.0 - s) + R * s)


# ---------------------------------------------------------------------------------------------- albedo
def albedo(
    n: np.ndarray, v: np.ndarray, alpha: float, fresnel, *, samples: int = 256, seed: int = 0
) -> np.ndarray:
    """E = ∫ f (n·l) dl per ray (numpy, (M, 3)): the mean of F(v·h) w over ``samples`` stratified half vectors
    (a Hammersley set rotated per ray, seeded). ``fresnel(cos) → (…, 3)`` reflectance at cos = v·h."""
    from study.backend import get

    B = get("numpy")
    u1, u2 = hammersley(samples)
    rot = np.random.default_rng(seed).random((len(n), 2))
    nn, vv = B.vec(np.asarray(n, float)), B.vec(np.asarray(v, float))
    out = np.zeros((len(n), 3))
    for i in range(samples):
        h = half_vectors(alpha, (u1[i] + rot[:, 0]) % 1.0, (u2[i] + rot[:, 1]) % 1.0)
        l, w = lobe_directions(B, nn, vv, (h[:, 0], h[:, 1], h[:, 2]), alpha)
        hv = B.normalize(V3(*(a + b for a, b in zip((l.x, l.y, l.z), (vv.x, vv.y, vv.z)))))
        cos = np.clip(np.asarray(hv.dot(vv), float), 0.0, 1.0)
        out += np.asarray(fresnel(cos)) * np.asarray(w, float)[:, None]
    return out / samples
