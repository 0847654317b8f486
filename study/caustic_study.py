"""Figure 8 and the caustic-map sweep: caustic maps measured against exact photon tracing (a) and Mitsuba (b).

What is compared with what (like with like):

* light maps, against (a): the caustic light maps of a method and of exact photon tracing (same photons, same
  splatting, Embree hits). RMSE and relMSE = mean (E − E_ref)² / (E_ref² + eps) are taken over the texels where
  either map is non-zero (eps in (W/m²)², from the config); the caustic energy ratio is Σ E·area / Σ E_ref·area.
* images, against (b): the *caustic-only* radiance on diffuse pixels (pixels whose every sub-pixel ray sees the
  room, not the sphere). Ours: albedo/π × E_caustic(u, v). Mitsuba: ``ptracer`` (max_depth 4) with the glass sphere
  minus ``ptracer`` with the same sphere made black (diffuse, reflectance 0): the black sphere casts the same shadow
  and has no specular paths, so the difference is every path with a specular bounce on the sphere — the
  refracted caustic (ours) plus the weak reflected caustic off the sphere's outside (not in ours, as in the paper).
  Mitsuba's own noise is stated from two seeds: RMS((D₁ − D₂)/2) of the seed-averaged difference D.
* the full image of the figure: ours = direct light (point light, shadow rays, the sphere opaque) + caustic light
  maps on the diffuse surfaces, the sphere shaded by Fresnel transmission of the impostor's radiance along the exit
  ray (same method) — no indirect light; Mitsuba = ptracer on diffuse pixels, ``path`` on the sphere's pixels.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from study import backend as backends
from study import caustics, lightmap, optics
from study.cache import Cache, content_key
from study.config import base_scene, expand_methods, read_toml
from study.errors import StudyError
from study.methods import Method
from study.reference.embree import Tracer
from study.results import write_csv
from study.scene import Scene, camera_rays
from study.shading import intersect_sphere


class CausticParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    res: int = Field(64, ge=2, le=2048)
    cube_res: int = Field(256, ge=4, le=4096)
    lightmap_res: int = Field(256, ge=8, le=4096)
    sigma: float = Field(0.02, gt=0)
    eps: float = Field(0.01, gt=0)


class MitsubaParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    spp: int = Field(1024, ge=1)
    seeds: list[int] = Field([1, 2], min_length=2)
    max_depth: int = Field(4, ge=4)


class CausticConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    scene: str | dict[str, Any]
    overrides: dict[str, Any] = {}
    methods: list[dict[str, Any]] = Field(min_length=1)
    show: str | None = None
    resolutions: list[int] = [16, 32, 64, 128, 256]
    caustic: CausticParams = CausticParams()
    mitsuba: MitsubaParams = MitsubaParams()


def load_config(path: str | Path) -> tuple[CausticConfig, Scene, list[Method]]:
    from pydantic import ValidationError
    path = Path(path)
    try:
        cfg = CausticConfig.model_validate(read_toml(path))
    except ValidationError as err:
        e = err.errors()[0]
        raise StudyError("unknown key" if e["type"] == "extra_forbidden" else e["msg"], file=str(path),
                         key=".".join(str(p) for p in e["loc"])) from None
    scene = base_scene(cfg.scene, config_path=path)
    if cfg.overrides:
        scene = scene.with_updates(cfg.overrides, source=f"{path} [overrides]")
    if scene.object.material.type != "dielectric":
        raise StudyError("caustics need a dielectric object", file=str(path), key="object.material")
    return cfg, scene, expand_methods(cfg.methods, source=str(path))


# ---------------------------------------------------------------------------------------------- camera side
class Receivers:
    """What the camera's sub-pixel rays see: room points (surface, uv, normal) or the sphere."""

    def __init__(self, scene: Scene, tracer: Tracer):
        o, d = camera_rays(scene.camera, scene.render.supersample)
        self.shape = d.shape[:3]
        o, d = o.reshape(-1, 3), d.reshape(-1, 3)
        h = tracer.intersect(o, d)
        ts = intersect_sphere(o, d, scene.object.center, scene.object.radius)
        self.on_sphere = ts < h["t"]
        self.surface = np.where(self.on_sphere, -1, h["surface"])
        self.uv, self.p, self.o, self.d, self.ts = h["uv"], h["point"], o, d, ts
        mesh = tracer.mesh
        V = mesh.vertices[mesh.faces[np.maximum(h["prim"], 0)]].astype(float)
        n = np.cross(V[:, 1] - V[:, 0], V[:, 2] - V[:, 0])
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        self.n = n * -np.sign(np.sum(n * d, -1, keepdims=True))     # facing the camera
        self.diffuse_px = (~self.on_sphere.reshape(self.shape)).all(-1)

    def image(self, values: np.ndarray) -> np.ndarray:
        """Per sub-pixel ray values (N, 3) → (H, W, 3) pixel means."""
        return values.reshape(*self.shape, 3).mean(axis=2)


def direct_irradiance(scene: Scene, tracer: Tracer, rec: Receivers) -> np.ndarray:
    """Point light irradiance I cosθ / d² with shadow rays (room geometry and the sphere, opaque): (N, 3)."""
    Lp = np.asarray(scene.light.position, float)
    p = np.nan_to_num(rec.p) + 1e-4 * rec.n
    v = Lp - p
    dist = np.linalg.norm(v, axis=-1)
    w = v / dist[:, None]
    blocked = tracer.intersect(p, w)["t"] < dist * (1 - 1e-4)
    blocked |= intersect_sphere(p, w, scene.object.center, scene.object.radius) < dist
    cos = np.maximum(np.sum(rec.n * w, -1), 0)
    E = np.asarray(scene.light.intensity)[None, :] * (cos / dist ** 2 * ~blocked)[:, None]
    return np.where((rec.surface >= 0)[:, None], E, 0.0)


def radiance(albedo: np.ndarray, rec: Receivers, E: np.ndarray) -> np.ndarray:
    """Diffuse radiance albedo/π · E of the room points (N, 3); 0 on the sphere."""
    return lightmap.sample(albedo, rec.surface, rec.uv) / np.pi * E


def sphere_radiance(scene: Scene, rec: Receivers, method: Method, env) -> np.ndarray:
    """Simple glass shading: Fresnel transmittance × impostor radiance at the localized exit-ray hit, plus Fresnel
    reflectance × radiance at the localized reflected-ray hit (N, 3), 0 off the sphere."""
    B, o = env.B, np.asarray(scene.reference.point, float)
    m = rec.on_sphere
    out = np.zeros((len(m), 3))
    if not m.any():
        return out
    x = rec.o[m] + rec.d[m] * rec.ts[m, None]
    N = (x - np.asarray(scene.object.center)) / scene.object.radius
    path = optics.through_sphere(x, rec.d[m], N, scene.object.center, scene.object.radius, scene.object.material.ior)
    R = optics.reflect(rec.d[m], N)
    F = optics.fresnel_dielectric(-np.sum(rec.d[m] * N, -1), 1 / scene.object.material.ior)
    cols = []
    for xs, ds in ((path.exit, path.out), (x, R)):
        tr = method.trace(B, env, B.vec(np.nan_to_num(xs - o)), B.vec(np.nan_to_num(ds)))
        cols.append(np.nan_to_num(B.to_numpy(tr.radiance).astype(float)))
    out[m] = path.transmittance[:, None] * cols[0] + F[:, None] * cols[1]
    return out


# ---------------------------------------------------------------------------------------------- Mitsuba (b)
def mitsuba_renders(scene: Scene, mp: MitsubaParams, cache: Cache) -> dict[str, np.ndarray]:
    """Seed-wise caustic-only images (glass − black sphere), their mean, the noise estimate, the full ptracer image
    and ``path`` for the sphere's pixels. Cached by content."""
    from study.reference.mitsuba import _sensor, mi, scene_dict
    m = mi()
    c = scene.camera
    base = [scene.room.model_dump(), [x.model_dump() for x in scene.columns], scene.light.model_dump(),
            scene.object.model_dump(), c.model_dump(), mp.spp, mp.max_depth, "caustic-v1"]

    def render(black: bool, integrator: str, seed: int) -> np.ndarray:
        sensor = _sensor(c.eye, c.target, c.up, c.fov, c.width, c.height, mp.spp, seed)
        d = scene_dict(scene, with_object=True, sensor=sensor,
                       integrator={"type": integrator, "max_depth": mp.max_depth})
        if black:
            d["object"]["bsdf"] = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
        return np.array(m.render(m.load_dict(d), seed=seed), dtype=np.float32)

    out = {}
    for black in (False, True):
        for seed in mp.seeds:
            key = content_key(*base, black, "ptracer", seed)
            out[f"pt_{'black' if black else 'glass'}_{seed}"] = cache.get(
                "caustic_mitsuba", key, lambda: render(black, "ptracer", seed)).reshape(c.height, c.width, 3)
    key = content_key(*base, False, "path", mp.seeds[0])
    out["path"] = cache.get("caustic_mitsuba", key,
                            lambda: render(False, "path", mp.seeds[0])).reshape(c.height, c.width, 3)
    D = [out[f"pt_glass_{s}"] - out[f"pt_black_{s}"] for s in mp.seeds[:2]]
    out["caustic"] = (D[0] + D[1]) / 2
    out["caustic_noise"] = (D[0] - D[1]) / 2
    out["full"] = (out[f"pt_glass_{mp.seeds[0]}"] + out[f"pt_glass_{mp.seeds[1]}"]) / 2
    return out


# ---------------------------------------------------------------------------------------------- metrics
def lightmap_errors(E: np.ndarray, Eref: np.ndarray, area: np.ndarray, eps: float) -> dict[str, float]:
    """E, Eref: (S, M, M, 3) irradiance; area (S,) m² per texel of each surface."""
    sup = ((E > 0) | (Eref > 0)).any(-1)
    d = (E - Eref)[sup]
    a = area[:, None, None, None]
    return {"lm_rmse": float(np.sqrt(np.mean(d ** 2))),
            "lm_relmse": float(np.mean(d ** 2 / (Eref[sup] ** 2 + eps))),
            "energy_ratio": float((E * a).sum() / max((Eref * a).sum(), 1e-300)),
            "lm_support_texels": int(sup.sum())}


def image_errors(img: np.ndarray, ref: np.ndarray, mask: np.ndarray, eps: float, suffix: str) -> dict[str, float]:
    d = (img - ref)[mask]
    return {f"img_rmse_{suffix}": float(np.sqrt(np.mean(d ** 2))),
            f"img_relmse_{suffix}": float(np.mean(d ** 2 / (ref[mask] ** 2 + eps))),
            f"img_sum_ratio_{suffix}": float(img[mask].sum() / ref[mask].sum())}   # caustic radiance ours / ref


# ---------------------------------------------------------------------------------------------- the study
class Setup:
    """Everything shared by the rows of a sweep: impostor, uv map, receivers, albedo, Mitsuba references."""

    def __init__(self, cfg: CausticConfig, scene: Scene, *, backend: str, cache: Cache, mitsuba: bool = True):
        from study.case import impostor
        self.cfg, self.scene = cfg, scene
        cp = cfg.caustic
        sc = scene.with_updates({"render.cube_res": cp.cube_res})
        self.tracer = Tracer(scene.mesh())
        self.B = backends.get(backend)
        self.imp = impostor(sc, cache, self.tracer)
        self.env = backends.EnvMap(self.imp.texels(), self.B)
        self.uvmap = lightmap.UVMap(lightmap.uv_map_texels(scene, cp.cube_res, self.tracer), self.B)
        self.frames = lightmap.SurfaceFrames.of(scene.mesh())
        self.area = self.frames.size_u * self.frames.size_v / cp.lightmap_res ** 2
        self.rec = Receivers(scene, self.tracer)
        self.albedo = lightmap.albedo_maps(scene.mesh())
        self.mask = self.rec.diffuse_px
        self.mi = mitsuba_renders(scene, cfg.mitsuba, cache) if mitsuba else None
        # radiance per unit caustic irradiance: albedo/π, so images are linear in E
        self.eps_img = cp.eps / np.pi ** 2 * 0.25          # (albedo ~ 0.5)·eps/π²: the image-space eps

    def lightmaps(self, cm: caustics.CausticMap) -> np.ndarray:
        cp = self.cfg.caustic
        return lightmap.splat(cm.surface, cm.uv, cm.power, self.frames, res=cp.lightmap_res, sigma=cp.sigma)

    def caustic_image(self, E: np.ndarray) -> np.ndarray:
        return self.rec.image(radiance(self.albedo, self.rec, lightmap.sample(E, self.rec.surface, self.rec.uv)))


def run_sweep(cfg: CausticConfig, scene: Scene, methods: list[Method], *, resolutions: list[int], setup: Setup,
              repeats: int = 3, progress=None) -> list[dict]:
    rows = []
    S = setup
    o = np.asarray(scene.reference.point, float)
    for res in resolutions:
        ex = caustics.exact_caustic_map(scene, S.tracer, res=res)
        Eref = S.lightmaps(ex)
        img_ref = S.caustic_image(Eref)
        base = {"caustic_res": res, "photons": int(ex.valid.sum()), "sigma_m": cfg.caustic.sigma,
                "lightmap_res": cfg.caustic.lightmap_res, "cube_res": cfg.caustic.cube_res, "eps": cfg.caustic.eps,
                "eps_img": S.eps_img, "backend": S.B.name}
        if S.mi is not None:
            rows.append({**base, "method": "exact", "label": "exact photon tracing (a)", "iterations": np.nan,
                         **lightmap_errors(Eref, Eref, S.area, cfg.caustic.eps),
                         **image_errors(img_ref, S.mi["caustic"], S.mask, S.eps_img, "mitsuba"),
                         "mitsuba_noise_rmse": float(np.sqrt(np.mean(S.mi["caustic_noise"][S.mask] ** 2)))})
        for m in methods:
            cm = caustics.build_caustic_map(scene, m, S.env, S.uvmap, res=res)
            E = S.lightmaps(cm)
            img = S.caustic_image(E)
            both = cm.valid & ex.valid
            seconds = caustics.time_caustic_map(scene, m, S.env, S.uvmap, res=res, repeats=repeats)
            from study.analytic import angle_deg
            ang = angle_deg(cm.shown[both] - cm.exit[both], ex.shown[both] - cm.exit[both])
            row = {**base, "method": m.name, "label": m.label, "iterations": getattr(m.params, "iterations", np.nan),
                   **lightmap_errors(E, Eref, S.area, cfg.caustic.eps),
                   **image_errors(img, img_ref, S.mask, S.eps_img, "exact"),
                   "photon_angle_median_deg": float(np.median(ang)) if ang.size else np.nan,
                   "photon_angle_p95_deg": float(np.percentile(ang, 95)) if ang.size else np.nan,
                   "photon_dist_median_m": float(np.median(np.linalg.norm(cm.shown[both] - ex.shown[both], axis=-1))),
                   "same_surface": float((cm.surface[both] == ex.surface[both]).mean()),
                   "seconds_per_map": seconds}
            if S.mi is not None:
                row.update(image_errors(img, S.mi["caustic"], S.mask, S.eps_img, "mitsuba"))
                row["mitsuba_noise_rmse"] = float(np.sqrt(np.mean(S.mi["caustic_noise"][S.mask] ** 2)))
            rows.append(row)
            if progress:
                progress(res, m.label)
    del o
    return rows


def sweep_plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    labels = list(dict.fromkeys(r["label"] for r in rows if r["method"] != "exact"))
    for lab in labels:
        rs = [r for r in rows if r["label"] == lab]
        x = [r["caustic_res"] for r in rs]
        axes[0].loglog(x, [r["lm_rmse"] for r in rs], "o-", label=lab)
        axes[1].semilogx(x, [r["energy_ratio"] for r in rs], "o-", label=lab)
        axes[2].loglog(x, [r.get("img_rmse_mitsuba", np.nan) for r in rs], "o-", label=lab)
        axes[3].loglog(x, [r["seconds_per_map"] * 1e3 for r in rs], "o-", label=lab)
    ex = [r for r in rows if r["method"] == "exact"]
    if ex:
        axes[2].loglog([r["caustic_res"] for r in ex], [r["img_rmse_mitsuba"] for r in ex], "k--",
                       label="exact photons (a)")
        axes[2].axhline(ex[0]["mitsuba_noise_rmse"], color="gray", ls=":", label="Mitsuba noise")
    for ax, t in zip(axes, ["light-map RMSE vs exact photons (W/m²)", "caustic energy ratio vs exact",
                            "caustic image RMSE vs Mitsuba", "ms per caustic map (CPU)"]):
        ax.set_title(t, fontsize=9); ax.set_xlabel("caustic-map resolution")
    axes[0].legend(fontsize=7); axes[2].legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def fig8(config: str | Path, out: str | Path, *, backend: str = "numpy", cache: str | Path | None = ".cache",
         sweep: bool = False, progress=None) -> list[dict]:
    """Figure 8 (``<out>/fig8.png``, ``<out>/fig8.csv``) and, with ``sweep``, the sweep (``<out>/sweep.csv``,
    ``<out>/sweep.png``) over the config's resolutions × methods. Returns the rows written."""
    from study.metrics import to_ldr
    cfg, scene, methods = load_config(config)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    S = Setup(cfg, scene, backend=backend, cache=Cache(cache))
    show = next((m for m in methods if m.label == (cfg.show or methods[-1].label)), None)
    if show is None:
        raise StudyError(f"show names {cfg.show!r}, not among the methods", file=str(config), key="show")
    res = cfg.caustic.res
    rows = run_sweep(cfg, scene, [show], resolutions=[res], setup=S)
    write_csv(rows, out / "fig8.csv")
    # ------------------------------------------------------------------ images
    cm = caustics.build_caustic_map(scene, show, S.env, S.uvmap, res=res)
    E = S.lightmaps(cm)
    Eref = S.lightmaps(caustics.exact_caustic_map(scene, S.tracer, res=res))
    Ed = direct_irradiance(scene, S.tracer, S.rec)
    Ec = lightmap.sample(E, S.rec.surface, S.rec.uv)
    ours_full = S.rec.image(radiance(S.albedo, S.rec, Ed + Ec) + sphere_radiance(scene, S.rec, show, S.env))
    sph = ~S.mask
    mi_full = np.where(sph[..., None], S.mi["path"], S.mi["full"])
    c_ours, c_ex, c_mi = S.caustic_image(E), S.caustic_image(Eref), S.mi["caustic"]
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 4, figsize=(15, 8))
    vmax = float(np.percentile(c_mi[S.mask].mean(-1), 99.9))
    def lum(a): return np.where(S.mask, a.mean(-1), np.nan)
    panels = [(ax[0, 0], to_ldr(ours_full), f"ours: direct + caustic map {res}², {show.label}"),
              (ax[0, 1], to_ldr(mi_full), "Mitsuba: ptracer (+ path on the sphere)"),
              (ax[1, 0], lum(c_ours), "caustic only: ours"),
              (ax[1, 1], lum(c_ex), "caustic only: exact photon tracing (a)"),
              (ax[1, 2], lum(c_mi), "caustic only: Mitsuba (glass − black sphere)")]
    for a, img, t in panels:
        a.imshow(img, cmap="inferno", vmin=0, vmax=vmax, interpolation="nearest") if img.ndim == 2 else a.imshow(img)
        a.set_title(t, fontsize=9)
    e1 = ax[0, 2].imshow(lum(c_ours - c_mi), cmap="coolwarm", vmin=-vmax / 2, vmax=vmax / 2)
    ax[0, 2].set_title("ours − Mitsuba (caustic only)", fontsize=9)
    ax[0, 3].imshow(lum(c_ours - c_ex), cmap="coolwarm", vmin=-vmax / 2, vmax=vmax / 2)
    ax[0, 3].set_title("ours − exact photons (caustic only)", fontsize=9)
    ax[1, 3].imshow(lum(S.mi["caustic_noise"]), cmap="coolwarm", vmin=-vmax / 2, vmax=vmax / 2)
    ax[1, 3].set_title("Mitsuba noise: (seed 1 − seed 2)/2", fontsize=9)
    fig.colorbar(e1, ax=ax[:, 3], fraction=0.03, label="radiance difference (W/m²/sr)")
    for a in ax.ravel():
        a.set_xticks([]); a.set_yticks([])
    r = rows[-1]
    fig.suptitle(f"fig8: glass sphere n={scene.object.material.ior}, caustic map {res}², {show.label}; "
                 f"image RMSE vs Mitsuba {r['img_rmse_mitsuba']:.3g} (Mitsuba noise {r['mitsuba_noise_rmse']:.3g}), "
                 f"light-map RMSE vs exact {r['lm_rmse']:.3g} W/m²", fontsize=10)
    fig.savefig(out / "fig8.png", dpi=100)
    plt.close(fig)
    if sweep:
        srows = run_sweep(cfg, scene, methods, resolutions=cfg.resolutions, setup=S, progress=progress)
        write_csv(srows, out / "sweep.csv")
        sweep_plot(srows, out / "sweep.png")
        rows = rows + srows
    return rows
