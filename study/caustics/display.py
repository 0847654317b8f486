"""Figure 8 as a person would publish it: the room with its indirect light, the sphere's shadow and a smooth
caustic — for the eye only. Nothing here feeds ``fig8.csv`` or the sweep: their light-map measures (``lm_rmse``,
``lm_relmse``, ``energy_ratio``, …) keep the fixed-σ splats of :func:`study.caustics.lightmap.splat`.

The published image of a caustic-map renderer (as in the paper and in Wyman & Dachsbacher 2006) is

    L = albedo/π · (E_direct + E_caustic) + L_indirect            on the room's pixels,
    L = Fresnel-weighted impostor radiance (the method)           on the sphere's pixels,

* ``E_direct``: the point light with shadow rays (:func:`study.caustics.study.direct_irradiance`): the sphere's
  shadow is hard, as a point light's is, and antialiased by the camera's sub-pixel rays.
* ``L_indirect``: baked indirect light, as games and GPU papers bake it into light maps: Mitsuba's ``path``
  render of the room with the sphere made black (so it has no caustic, and casts the same shadow) minus Mitsuba's
  ``direct`` render of the same scene (:func:`mitsuba_indirect`; ``max_depth`` from the config's ``[mitsuba]``,
  :data:`INDIRECT_SPP` samples per pixel). It is what fills the shadow and the room in Mitsuba's image too.
* Mitsuba's image beside it: ``ptracer`` on the room's pixels (the caustic needs it), on the sphere's pixels
  ``path`` with the glass sphere and two more bounces (:func:`mitsuba_display`).
* ``E_caustic``: the caustic map's photons splatted with a radius adaptive to the photon density
  (:func:`knn_sigma`): each photon's Gaussian σ_p = max(σ, min(σ_max, h_p)), h_p = r_k √(π/k) the local photon
  spacing from the distance r_k to its k-th nearest neighbour on the same surface (metres) — a k-nearest-neighbour
  density estimate, so the bright focus keeps the config's σ and the sparse rim becomes a smooth glow instead of
  separate discs. Each splat is renormalised like the fixed one: the caustic's power is unchanged.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from study.cache import Cache, content_key
from study.caustics import lightmap
from study.caustics.photons import CausticMap
from study.io import atomic_savefig
from study.measure.metrics import to_ldr
from study.reference.mitsuba import mi, scene_dict, sensor
from study.scene import Scene
from study.scene.environment import env_key
from study.scene.sources import key_fields

K_NEIGHBOURS = 8  # photons in the k-nearest-neighbour radius
SIGMA_MAX = 0.08  # metres: the widest splat (a lone photon at the rim)
INDIRECT_SPP = 256  # samples per pixel of the two Mitsuba renders behind the baked indirect light
_BINS_PER_OCTAVE = 4  # σ is rounded to 2^(1/4) steps, so photons of one step are splatted together
_CHUNK = 256  # photons per splat call (bounds memory at the widest σ)


def knn_sigma(
    surface: np.ndarray,
    uv: np.ndarray,
    frames: lightmap.SurfaceFrames,
    *,
    sigma: float,
    k: int = K_NEIGHBOURS,
    sigma_max: float = SIGMA_MAX,
) -> np.ndarray:
    """Per-photon splat width from the photon density.

    Parameters
    ----------
    surface : (P,) texture id of each photon (< 0: invalid)
    uv : (P, 2) texture coordinates of the hits
    frames : metres per unit u, v of each surface
    sigma : the smallest σ (metres), the config's fixed splat width
    k : neighbours counted (the photon itself excluded)
    sigma_max : the largest σ (metres)

    Returns
    -------
    (P,) σ in metres; NaN for invalid photons. σ_p = clip(r_k √(π/k), sigma, sigma_max), r_k the distance to the
    k-th nearest photon on the same surface (a surface with at most k photons: sigma_max).
    """
    out = np.full(len(surface), np.nan)
    ok = (surface >= 0) & np.all(np.isfinite(uv), -1)
    for s in np.unique(surface[ok]):
        idx = np.nonzero(ok & (surface == s))[0]
        if idx.size <= k:
            out[idx] = sigma_max
            continue
        xy = uv[idx] * np.array([frames.size_u[s], frames.size_v[s]])
        r, _ = cKDTree(xy).query(xy, k=k + 1)  # column 0 is the photon itself
        out[idx] = np.clip(r[:, -1] * np.sqrt(np.pi / k), sigma, sigma_max)
    return out


def splat_adaptive(
    cm: CausticMap,
    frames: lightmap.SurfaceFrames,
    *,
    res: int,
    sigma: float,
    k: int = K_NEIGHBOURS,
    sigma_max: float = SIGMA_MAX,
) -> np.ndarray:
    """The caustic map's photons splatted with :func:`knn_sigma` widths: (S, M, M, 3) irradiance, W/m².
    Photons whose σ round to the same 2^(1/4) step share one :func:`study.caustics.lightmap.splat` call."""
    S = len(frames.size_u)
    E = np.zeros((S, res, res, 3))
    sig = knn_sigma(cm.surface, cm.uv, frames, sigma=sigma, k=k, sigma_max=sigma_max)
    ok = np.isfinite(sig)
    step = np.rint(np.log2(np.where(ok, sig, sigma) / sigma) * _BINS_PER_OCTAVE).astype(int)
    for b in np.unique(step[ok]):
        idx = np.nonzero(ok & (step == b))[0]
        sb = min(sigma * 2 ** (b / _BINS_PER_OCTAVE), sigma_max)
        for c in range(0, idx.size, _CHUNK):
            i = idx[c : c + _CHUNK]
            E += lightmap.splat(cm.surface[i], cm.uv[i], cm.power[i], frames, res=res, sigma=sb)
    return E


def mitsuba_display(
    scene: Scene, max_depth: int, cache: Cache, *, spp: int = INDIRECT_SPP, seed: int = 1
) -> dict[str, np.ndarray]:
    """Mitsuba renders (H, W, 3), W/m²/sr, for the display, cached by content: ``path`` (``max_depth``) and
    ``direct`` of the room with the sphere made black (it casts its shadow and has no specular paths), and
    ``glass``: ``path`` with the glass sphere and ``max_depth + 2`` (in and out of the glass, as
    :func:`study.reference.mitsuba.scene_dict` gives a dielectric), for the sphere's own pixels — at
    ``max_depth`` the walls seen through the sphere would lack their indirect light."""
    c = scene.camera
    base = [
        env_key(scene),
        scene.light.model_dump(),
        key_fields(scene.object),
        c.model_dump(),
        spp,
        max_depth,
        seed,
        "display-v1",
    ]

    def render(integrator: dict, black: bool) -> np.ndarray:
        m = mi()
        d = scene_dict(
            scene,
            with_object=True,
            sensor=sensor(c.eye, c.target, c.up, c.fov, c.width, c.height, spp, seed),
            integrator=integrator,
        )
        if black:
            d["object"]["bsdf"] = {
                "type": "diffuse",
                "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]},
            }
        return np.array(m.render(m.load_dict(d), seed=seed), dtype=np.float32)

    todo = {
        "path": ({"type": "path", "max_depth": max_depth}, True),
        "direct": ({"type": "direct"}, True),
        "glass": ({"type": "path", "max_depth": max_depth + 2}, False),
    }
    return {
        k: cache.get(
            "caustic_mitsuba", content_key(*base, k), lambda a=args: render(*a), code=render
        ).reshape(c.height, c.width, 3)
        for k, args in todo.items()
    }


def mitsuba_indirect(
    scene: Scene, max_depth: int, cache: Cache, *, spp: int = INDIRECT_SPP, seed: int = 1
) -> np.ndarray:
    """Baked indirect light (H, W, 3), W/m²/sr: Mitsuba ``path`` minus ``direct`` of the room with the black
    sphere (:func:`mitsuba_display`), clipped at 0."""
    r = mitsuba_display(scene, max_depth, cache, spp=spp, seed=seed)
    return np.maximum(r["path"] - r["direct"], 0.0)


def draw(path, *, ours, mitsuba, mitsuba_noise, caustics: dict, measured, mask, title: str) -> None:
    """Figure 8's PNG. Top: the published image (ours), Mitsuba's, their luminance difference and Mitsuba's own
    noise. Bottom: caustic-only radiance (``caustics``: panel title → (H, W, 3), the first two adaptive splats,
    the third Mitsuba's) and ``measured``, the difference of the fixed-σ light maps that ``fig8.csv`` measures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 4, figsize=(16, 8.6))
    c_mi = list(caustics.values())[-1]
    vmax = float(np.percentile(c_mi[mask].mean(-1), 99.9))

    def lum(a, m=mask):
        return np.where(m, a.mean(-1), np.nan)

    everywhere = np.ones_like(mask)
    for a, img, t in (
        (ax[0, 0], ours, "ours: direct + baked indirect + caustic map"),
        (ax[0, 1], mitsuba, "Mitsuba: ptracer (path on the sphere)"),
    ):
        a.imshow(to_ldr(img), interpolation="nearest")
        a.set_title(t, fontsize=9)
    for a, (t, img) in zip(ax[1, :3], caustics.items()):
        a.imshow(lum(img), cmap="inferno", vmin=0, vmax=vmax, interpolation="nearest")
        a.set_title(t, fontsize=9)
    diffs = (
        (ax[0, 2], lum(ours - mitsuba, everywhere), "ours − Mitsuba (whole image)"),
        (ax[0, 3], lum(mitsuba_noise, everywhere), "Mitsuba noise: (seed 1 − seed 2)/2"),
        (ax[1, 3], lum(measured), "caustic: ours − exact photons,\nfixed-σ light maps (as in fig8.csv)"),
    )
    for a, img, t in diffs:
        e = a.imshow(img, cmap="coolwarm", vmin=-vmax / 2, vmax=vmax / 2, interpolation="nearest")
        a.set_title(t, fontsize=9)
    for a in ax.ravel():
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle(title, fontsize=9.5)
    fig.tight_layout(rect=(0, 0, 0.93, 1))
    fig.colorbar(e, cax=fig.add_axes((0.94, 0.15, 0.012, 0.7)), label="luminance difference (W/m²/sr)")
    atomic_savefig(fig, path, dpi=100)
