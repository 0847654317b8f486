"""Prefiltered impostors: a mip chain of the impostor's radiance convolved with the GGX lobe (the split-sum
approximation, Karis 2013), and its lookup by roughness and footprint.

Level m of ``LEVELS`` holds roughness r_m = m/(LEVELS − 1), α_m = r_m² (level 0 is the impostor itself, α = 0; the
last α = 1), at face resolution :func:`level_res`. Each texel of direction n holds

    L_m(n) = ∫ L(l) D(h)(n·l)⁺ dl / ∫ D(h)(n·l)⁺ dl,   h = (n + l)/|n + l|,

the GGX lobe's average with the view along the normal (v = n = R): the split sum's assumption, which loses the
lobe's stretch at grazing angles. The integral is estimated with ``samples`` Hammersley half vectors per texel,
each read from the box-filtered chain of the impostor at the level whose texel matches the sample's solid angle
(filtered importance sampling, Colbert and Křivánek 2007, without their +1 bias and never coarser than 8 texels
a face: a face-sized texel would blur across the faces' edges), so a few hundred samples give a smooth result.
The impostor's distance channel is convolved with the same weights: the distance mips hold the lobe-weighted
*mean* distance (where a lobe sees no surface, ``cubemap.FAR`` enters that mean).

The convolution *without* the split sum's assumption depends on v and n of every shading point: that is the
``stochastic`` method (:mod:`study.methods.stochastic`) with ``localize = false``, the lobe sampled from the
reference point.

A lookup (:meth:`MipChain.lookup`) blends the two levels around r = √α (trilinear, one filtered fetch on a GPU).
The footprint of the lobe seen from the reference point o rather than from the shading point x is narrower by
|hit − x| / |hit − o|; :func:`footprint_alpha` scales α so (Lagarde 2012's distance-based roughness).
"""

from __future__ import annotations

import numpy as np

from study.backend import V3, Backend, get
from study.impostor import cubemap, ggx
from study.impostor.envmap import EnvMap

LEVELS = 6  # roughness levels 0, 0.2, …, 1 (α = 0, 0.04, 0.16, 0.36, 0.64, 1)
SAMPLES = 256  # half vectors per texel


def level_alpha(m: int, levels: int = LEVELS) -> float:
    """α of level m: (m / (levels − 1))²."""
    return (m / (levels - 1)) ** 2


def level_res(res: int, alpha: float) -> int:
    """Face resolution of the level of roughness α: the impostor's for α = 0, else enough texels for about
    six per lobe width (texel ≈ π/2/res radians, lobe ≈ α), at least 8 and at most the impostor's."""
    if alpha <= 0:
        return res
    want = 2 ** int(np.ceil(np.log2(6.0 * np.pi / 2 / alpha)))
    return int(min(res, max(8, want)))


def box_chain(texels: np.ndarray) -> list[np.ndarray]:
    """The impostor and its 2 × 2 box-filtered halvings down to 1 × 1 per face (resolution a power of two, or
    stopped at the first odd one)."""
    chain = [np.asarray(texels, np.float64)]
    while chain[-1].shape[1] % 2 == 0 and chain[-1].shape[1] > 1:
        t = chain[-1]
        chain.append(0.25 * (t[:, ::2, ::2] + t[:, 1::2, ::2] + t[:, ::2, 1::2] + t[:, 1::2, 1::2]))
    return chain


def convolve(texels: np.ndarray, alpha: float, res: int, samples: int = SAMPLES) -> np.ndarray:
    """One level: the split-sum convolution (module docstring) of ``texels`` (6, R, R, C) with the GGX lobe of
    roughness α, at face resolution ``res``. Returns (6, res, res, C) float32."""
    B = get("numpy")
    chain = box_chain(texels)
    maps = [EnvMap(t.astype(np.float32), B) for t in chain]
    R0 = texels.shape[1]
    u1, u2 = ggx.hammersley(samples)
    h = ggx.half_vectors(alpha, u1, u2)  # (S, 3), local
    pdf = ggx.ndf(h[:, 2], alpha) / 4.0  # density of l when v = n: D(h)(n·h)/(4 v·h), v·h = n·h
    omega_s = 1.0 / (samples * pdf)  # solid angle per sample
    omega_p = 4.0 * np.pi / (6.0 * R0 * R0)  # per texel of level 0
    coarsest = max(0.0, min(len(chain) - 1.0, np.log2(max(R0 / 8, 1))))  # ≥ 8 texels a face: no face blur
    lod = np.clip(0.5 * np.log2(omega_s / omega_p), 0.0, coarsest)
    n = cubemap.texel_directions(res).reshape(-1, 3)
    C = texels.shape[-1]
    acc, wsum = np.zeros((len(n), C)), np.zeros(len(n))
    nv = B.vec(n)
    for i in range(samples):
        l, _ = ggx.lobe_directions(B, nv, nv, (h[i, 0], h[i, 1], h[i, 2]), alpha)
        wl = np.clip(np.asarray(nv.dot(l), float), 0.0, None)  # (n·l)⁺
        lo = int(np.floor(lod[i]))
        hi, f = min(lo + 1, len(chain) - 1), lod[i] - np.floor(lod[i])
        val = (1 - f) * np.stack(maps[lo].lookup(l), -1) + f * np.stack(maps[hi].lookup(l), -1)
        acc += val * wl[:, None]
        wsum += wl
    out = acc / np.maximum(wsum, 1e-30)[:, None]
    return out.reshape(6, res, res, C).astype(np.float32)


def prefilter(texels: np.ndarray, levels: int = LEVELS, samples: int = SAMPLES) -> list[np.ndarray]:
    """The mip chain: level 0 = ``texels`` (6, R, R, C), level m its convolution at α_m (:func:`convolve`)."""
    R = texels.shape[1]
    out = [np.asarray(texels, np.float32)]
    for m in range(1, levels):
        a = level_alpha(m, levels)
        out.append(convolve(texels, a, level_res(R, a), samples))
    return out


def footprint_alpha(B: Backend, alpha: float, x: V3, hit: V3):
    """α seen from the reference point o for a lobe of roughness α at x whose rays end near ``hit`` (both
    relative to o): α |hit − x| / |hit|, at most 1 (Lagarde 2012); per ray."""
    d_x = B.length(hit - x)
    d_o = B.maximum(B.length(hit), 1e-6)
    return B.minimum(d_x * (alpha / 1.0) / d_o, d_x * 0.0 + 1.0)


class MipChain:
    """The mip chain of :func:`prefilter` bound to a backend: ``lookup(v, alpha)`` → (r, g, b, mean distance)
    blended between the levels around r = √α (``alpha``: a number or one value per ray)."""

    def __init__(self, levels: list[np.ndarray], B: Backend):
        self.B = B
        self.maps = [EnvMap(t, B) for t in levels]
        self.res = levels[0].shape[1]

    def lookup(self, v: V3, alpha) -> list:
        B, L = self.B, len(self.maps)
        r = B.sqrt(B.minimum(B.maximum(v.x * 0.0 + alpha, 0.0), 1.0))
        mf = r * float(L - 1)
        out = None
        for m, mp in enumerate(self.maps):
            w = B.maximum(1.0 - B.abs(mf - float(m)), 0.0)  # hat: the two levels around mf
            vals = [c * w for c in mp.lookup(v)]
            out = vals if out is None else [a + b for a, b in zip(out, vals)]
        return out
