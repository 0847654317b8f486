"""The caustic study: caustic maps measured against exact photon tracing (a) and Mitsuba (b) (figure and sweep:
:mod:`study.caustics.figure`).

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

from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from study import backend as backends
from study.cache import Cache, content_key
from study.caustics import lightmap
from study.caustics import photons as caustics
from study.errors import StudyError
from study.harness.config import MethodSpecs, configured_scene, expand_methods
from study.impostor.analytic import angle_deg
from study.measure.case import knob_columns
from study.measure.inputs import capture_views, impostor
from study.methods import Method
from study.optics import interfaces as optics
from study.reference.embree import Tracer
from study.reference.mitsuba import mi, scene_dict, sensor
from study.reference.tracer import make_tracer
from study.scene import Scene, camera_rays
from study.scene.environment import env_key
from study.scene.objects import intersect_sphere
from study.scene.sources import key_fields
from study.validation import validate_file


class CausticParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    res: int = Field(64, ge=2, le=2048)
    cube_res: int = Field(256, ge=4, le=4096)
    lightmap_res: int = Field(256, ge=8, le=4096)
    sigma: float = Field(0.02, gt=0, allow_inf_nan=False)
    eps: float = Field(0.01, gt=0, allow_inf_nan=False)


class MitsubaParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    spp: int = Field(1024, ge=1, le=1 << 20)
    seeds: list[int] = Field([1, 2], min_length=2, max_length=16)
    max_depth: int = Field(4, ge=4, le=64)

    @field_validator("seeds")
    @classmethod
    def _distinct(cls, v):
        if len(set(v)) != len(v):
            raise ValueError("seeds must differ (the references' noise is estimated from two distinct seeds)")
        return v


class CausticConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    scene: str | dict[str, Any]
    overrides: dict[str, Any] = {}
    methods: MethodSpecs = "all"
    show: str | None = None
    resolutions: list[Annotated[int, Field(ge=2, le=2048)]] = Field(
        [16, 32, 64, 128, 256], min_length=1, max_length=32
    )
    caustic: CausticParams = CausticParams()
    mitsuba: MitsubaParams = MitsubaParams()
    kind: Literal["caustics"] = "caustics"  # the figure kind (study.report.kinds.caustics)

    @field_validator("resolutions")
    @classmethod
    def _distinct(cls, v):
        if len(set(v)) != len(v):
            raise ValueError("resolutions must differ (each is one row per method)")
        return v


#: Bytes per entry of the splatting kernel's window (indices, weights, offsets: int64/float64, a few copies) and
#: per light-map texel (RGB float64, the map and its copies); measured loosely, meant to catch orders of magnitude.
BYTES_PER_SPLAT_ENTRY, BYTES_PER_LIGHTMAP_TEXEL = 96, 4 * 3 * 8


def check_budget(cfg: CausticConfig, scene: Scene, *, sweep: bool, source: str | None = None) -> None:
    """Refuse (one line naming the key) a caustics run whose splatting or light maps need more memory than
    ``--max-memory``, or whose Mitsuba references would take longer than ``--max-minutes``, before any work."""
    from study.harness.budget import LIMITS, MITSUBA_SAMPLES_PER_S

    cp, mp, cam = cfg.caustic, cfg.mitsuba, scene.camera
    frames = lightmap.SurfaceFrames.of(scene.mesh())
    K = int(np.ceil(3 * cp.sigma / (min(frames.size_u.min(), frames.size_v.min()) / cp.lightmap_res)))
    res = max([cp.res, *(cfg.resolutions if sweep else [])])
    mem = {
        "caustic.res": res**2 * (2 * K + 1) ** 2 * BYTES_PER_SPLAT_ENTRY,  # photons × kernel window
        "caustic.lightmap_res": len(frames.size_u) * cp.lightmap_res**2 * BYTES_PER_LIGHTMAP_TEXEL,
    }
    if sum(mem.values()) > LIMITS.max_memory_gib * (1 << 30):
        key = max(mem, key=mem.get)
        raise StudyError(
            f"would need about {sum(mem.values()) / (1 << 30):.1f} GiB, over the limit of "
            f"{LIMITS.max_memory_gib:g} GiB (--max-memory); most of it for {key} "
            f"(with caustic.sigma = {cp.sigma:g} m the splatting window is {2 * K + 1}² texels): lower it",
            file=source,
            key=key,
        )
    renders = 2 * len(mp.seeds) + 1  # ptracer with glass and black object per seed, one path render
    seconds = renders * cam.width * cam.height * mp.spp / (MITSUBA_SAMPLES_PER_S * 4 / mp.max_depth)
    if seconds > LIMITS.max_minutes * 60:
        raise StudyError(
            f"the Mitsuba references would take about {seconds / 3600:.1f} h here, over the limit of "
            f"{LIMITS.max_minutes:g} min (--max-minutes): lower mitsuba.spp or the number of mitsuba.seeds",
            file=source,
            key="mitsuba.spp",
        )


def load_caustic_config(path: str | Path) -> tuple[CausticConfig, Scene, list[Method]]:
    path = Path(path)
    cfg = validate_file(CausticConfig, path)
    scene = configured_scene(cfg, path)
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
        self.n = n * -np.sign(np.sum(n * d, -1, keepdims=True))  # facing the camera
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
    E = np.asarray(scene.light.intensity)[None, :] * (cos / dist**2 * ~blocked)[:, None]
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
    path = optics.through_sphere(
        x, rec.d[m], N, scene.object.center, scene.object.radius, scene.object.material.ior
    )
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
    m = mi()
    c = scene.camera
    base = [
        env_key(scene),
        scene.light.model_dump(),
        key_fields(scene.object),
        c.model_dump(),
        mp.spp,
        mp.max_depth,
        "caustic-v1",
    ]

    def render(black: bool, integrator: str, seed: int) -> np.ndarray:
        cam = sensor(c.eye, c.target, c.up, c.fov, c.width, c.height, mp.spp, seed)
        d = scene_dict(
            scene, with_object=True, sensor=cam, integrator={"type": integrator, "max_depth": mp.max_depth}
        )
        if black:
            d["object"]["bsdf"] = {
                "type": "diffuse",
                "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]},
            }
        return np.array(m.render(m.load_dict(d), seed=seed), dtype=np.float32)

    out = {}
    for black in (False, True):
        for seed in mp.seeds:
            key = content_key(*base, black, "ptracer", seed)
            out[f"pt_{'black' if black else 'glass'}_{seed}"] = cache.get(
                "caustic_mitsuba",
                key,
                lambda: render(black, "ptracer", seed),  # noqa: B023 (called at once)
                code=render,
            ).reshape(c.height, c.width, 3)
    key = content_key(*base, False, "path", mp.seeds[0])
    out["path"] = cache.get(
        "caustic_mitsuba", key, lambda: render(False, "path", mp.seeds[0]), code=render
    ).reshape(c.height, c.width, 3)
    D = [out[f"pt_glass_{s}"] - out[f"pt_black_{s}"] for s in mp.seeds[:2]]
    out["caustic"] = (D[0] + D[1]) / 2
    out["caustic_noise"] = (D[0] - D[1]) / 2
    out["full"] = (out[f"pt_glass_{mp.seeds[0]}"] + out[f"pt_glass_{mp.seeds[1]}"]) / 2
    return out


# ---------------------------------------------------------------------------------------------- metrics
def lightmap_errors(Eref: np.ndarray, E: np.ndarray, area: np.ndarray, eps: float) -> dict[str, float]:
    """Eref (the reference), E: (S, M, M, 3) irradiance; area (S,) m² per texel of each surface."""
    sup = ((E > 0) | (Eref > 0)).any(-1)
    d = (E - Eref)[sup]
    a = area[:, None, None, None]
    return {
        "lm_rmse": float(np.sqrt(np.mean(d**2))),
        "lm_relmse": float(np.mean(d**2 / (Eref[sup] ** 2 + eps))),
        "energy_ratio": float((E * a).sum() / max((Eref * a).sum(), 1e-300)),
        "lm_support_texels": int(sup.sum()),
    }


def caustic_image_errors(
    ref: np.ndarray, img: np.ndarray, mask: np.ndarray, eps: float, suffix: str
) -> dict[str, float]:
    d = (img - ref)[mask]
    return {
        f"img_rmse_{suffix}": float(np.sqrt(np.mean(d**2))),
        f"img_relmse_{suffix}": float(np.mean(d**2 / (ref[mask] ** 2 + eps))),
        f"img_sum_ratio_{suffix}": float(img[mask].sum() / ref[mask].sum()),
    }  # caustic radiance ours / ref


# ---------------------------------------------------------------------------------------------- the study
class CausticSetup:
    """Everything shared by the rows of a sweep: impostor, uv map, receivers, albedo, Mitsuba references."""

    def __init__(
        self,
        cfg: CausticConfig,
        scene: Scene,
        *,
        backend: str,
        cache: Cache,
        mitsuba: bool = True,
        methods: list[Method] = (),
    ):
        self.cfg, self.scene = cfg, scene
        if scene.environment.type != "box":  # light maps are laid out on the box room's six walls and columns
            raise StudyError(
                f"caustic maps need the box room; environment.type is {scene.environment.type!r}",
                key="environment.type",
            )
        cp = cfg.caustic
        sc = scene.with_updates({"render.cube_res": cp.cube_res})
        self.tracer = make_tracer(scene.mesh())
        self.B = backends.get(backend)
        self.imp = impostor(sc, cache, self.tracer)
        # what the methods search, as a case captures it (scene knowledge, layers, probes, the camera's buffer)
        self.env = capture_views(sc, list(methods), self.imp, self.B, cache=cache, tracer=self.tracer)
        self.uvmap = lightmap.UVMap(lightmap.uv_map_texels(scene, cp.cube_res, self.tracer), self.B)
        self.frames = lightmap.SurfaceFrames.of(scene.mesh())
        self.area = self.frames.size_u * self.frames.size_v / cp.lightmap_res**2
        self.rec = Receivers(scene, self.tracer)
        self.albedo = lightmap.albedo_maps(scene.mesh())
        self.mask = self.rec.diffuse_px
        self.mi = mitsuba_renders(scene, cfg.mitsuba, cache) if mitsuba else None
        # radiance per unit caustic irradiance: albedo/π, so images are linear in E
        self.eps_img = cp.eps / np.pi**2 * 0.25  # (albedo ~ 0.5)·eps/π²: the image-space eps

    def lightmaps(self, cm: caustics.CausticMap) -> np.ndarray:
        cp = self.cfg.caustic
        return lightmap.splat(cm.surface, cm.uv, cm.power, self.frames, res=cp.lightmap_res, sigma=cp.sigma)

    def caustic_image(self, E: np.ndarray) -> np.ndarray:
        return self.rec.image(
            radiance(self.albedo, self.rec, lightmap.sample(E, self.rec.surface, self.rec.uv))
        )


def caustic_rows(
    cfg: CausticConfig,
    scene: Scene,
    methods: list[Method],
    *,
    resolutions: list[int],
    setup: CausticSetup,
    repeats: int = 3,
    progress=None,
) -> list[dict]:
    """One row per caustic-map resolution × method (and one for exact photon tracing where Mitsuba is known):
    light-map errors against exact photon tracing (a), caustic-image errors against it and against Mitsuba (b),
    photon-hit angles, time per caustic map."""
    rows = []
    S = setup
    for res in resolutions:
        ex = caustics.exact_caustic_map(scene, S.tracer, res=res)
        Eref = S.lightmaps(ex)
        img_ref = S.caustic_image(Eref)
        base = {
            "caustic_res": res,
            "photons": int(ex.valid.sum()),
            "sigma_m": cfg.caustic.sigma,
            "lightmap_res": cfg.caustic.lightmap_res,
            "cube_res": cfg.caustic.cube_res,
            "eps": cfg.caustic.eps,
            "eps_img": S.eps_img,
            "backend": S.B.name,
        }
        if S.mi is not None:
            rows.append(
                {
                    **base,
                    "method": "exact",
                    "label": "exact photon tracing (a)",
                    "family": "exact",
                    "knob": "",
                    "knob_value": np.nan,
                    **lightmap_errors(Eref, Eref, S.area, cfg.caustic.eps),
                    **caustic_image_errors(S.mi["caustic"], img_ref, S.mask, S.eps_img, "mitsuba"),
                    "mitsuba_noise_rmse": float(np.sqrt(np.mean(S.mi["caustic_noise"][S.mask] ** 2))),
                }
            )
        for m in methods:
            cm = caustics.build_caustic_map(scene, m, S.env, S.uvmap, res=res)
            E = S.lightmaps(cm)
            img = S.caustic_image(E)
            both = cm.valid & ex.valid
            seconds = caustics.time_caustic_map(scene, m, S.env, S.uvmap, res=res, repeats=repeats)
            ang = angle_deg(cm.shown[both] - cm.exit[both], ex.shown[both] - cm.exit[both])
            row = {
                **base,
                "method": m.name,
                "label": m.label,
                **knob_columns(m),
                **lightmap_errors(Eref, E, S.area, cfg.caustic.eps),
                **caustic_image_errors(img_ref, img, S.mask, S.eps_img, "exact"),
                "photon_angle_median_deg": float(np.median(ang)) if ang.size else np.nan,
                "photon_angle_p95_deg": float(np.percentile(ang, 95)) if ang.size else np.nan,
                "photon_dist_median_m": float(
                    np.median(np.linalg.norm(cm.shown[both] - ex.shown[both], axis=-1))
                ),
                "same_surface": float((cm.surface[both] == ex.surface[both]).mean()),
                "seconds_per_map": seconds,
            }
            if S.mi is not None:
                row.update(caustic_image_errors(S.mi["caustic"], img, S.mask, S.eps_img, "mitsuba"))
                row["mitsuba_noise_rmse"] = float(np.sqrt(np.mean(S.mi["caustic_noise"][S.mask] ** 2)))
            rows.append(row)
            if progress:
                progress(res, m.label)
    return rows
