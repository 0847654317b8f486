"""One case end to end: capture → shade the object with each method → references → metrics.

A reader can follow one ray here: camera ray → object (``shading.object_rays``) → reflected ray (x, R) →
``method.trace`` on the chosen backend → shown point and radiance → Fresnel → composited image; the same ray →
Embree exact hit → outcome class and angular error; the images → image error against the oracle_map, the
truth_at_hit and Mitsuba, and the error decomposition (:mod:`study.measure.truth`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from study import backend as backends
from study.cache import Cache, content_key
from study.errors import StudyError
from study.impostor import probes, screen
from study.impostor.capture import Impostor, capture_distance, impostor_key, render_cube
from study.impostor.cubemap import FAR, FAR_MIN
from study.impostor.envmap import EnvMap
from study.impostor.layers import layered_impostor
from study.impostor.views import Captured, Views
from study.measure import metrics, outcomes, stats, truth
from study.methods import Method
from study.optics import shading
from study.reference.embree import Tracer
from study.reference.mitsuba import render_camera
from study.reference.tracer import make_tracer
from study.scene import Scene
from study.scene.environment import env_key
from study.scene.sources import key_fields


@dataclass
class CaseOutput:
    scene: Scene
    rows: list[dict]  # one per method (and one for the oracle)
    images: dict[str, np.ndarray] = field(default_factory=dict)  # label → (H, W, 3) linear RGB
    angle_maps: dict[str, np.ndarray] = field(default_factory=dict)  # label → (H, W) mean angular error, deg
    outcome_maps: dict[str, np.ndarray] = field(default_factory=dict)  # label → (H, W) majority outcome class
    #   (codes of study.measure.outcomes: 0 correct … 3 no hit; ties to the worse; NaN off the object)
    flip_maps: dict[str, np.ndarray] = field(
        default_factory=dict
    )  # label → (H, W) LDR-FLIP against truth_at_hit
    #   (metrics.flip_map over the whole frame; the flip_truth column is its mean over ``mask``)
    oracle: np.ndarray | None = None  # (H, W, 3) what a perfect localization shows
    mitsuba: np.ndarray | None = None  # (H, W, 3) Mitsuba's render with the object (2 seeds)
    truth: np.ndarray | None = None  # (H, W, 3) truth_at_hit composited (study.measure.truth)
    occluded: np.ndarray | None = None  # (H, W) fraction of sub-pixel rays occluded from o
    mask: np.ndarray | None = None  # (H, W) pixels fully on the object


# ---------------------------------------------------------------------------------------------- cached inputs
def impostor(scene: Scene, cache: Cache, tracer: Tracer | None = None) -> Impostor:
    r = scene.render
    key = impostor_key(scene)
    rad = cache.get("radiance", key, lambda: render_cube(scene, r.cube_res, r.cube_spp), code=render_cube)
    dist = cache.get(
        "distance", key, lambda: capture_distance(scene, r.cube_res, tracer), code=capture_distance
    )
    return Impostor(
        np.asarray(scene.reference.point, float),
        rad.reshape(6, r.cube_res, r.cube_res, 3),
        dist.reshape(6, r.cube_res, r.cube_res),
    )


def camera_render(scene: Scene, cache: Cache, *, with_object: bool) -> np.ndarray:
    s = scene
    parts = [
        env_key(s),
        s.light.model_dump(),
        s.camera.model_dump(),
        s.render.spp,
        s.render.max_depth,
        s.render.seed,
        "v2",
    ]
    if with_object:
        parts.append(key_fields(s.object))  # a mesh file by its bytes
        if s.object.material.type == "dielectric":
            parts.append("dielectric depth +2")  # see mitsuba.scene_dict
    key = content_key(*parts)
    img = cache.get(
        "mitsuba" if with_object else "background",
        key,
        lambda: render_camera(scene, with_object=with_object),
        code=render_camera,
    )
    return img.reshape(s.camera.height, s.camera.width, 3)


def env_info(scene: Scene) -> dict:
    """The scene knowledge methods may use (fields of :class:`~study.impostor.views.Captured`): reference point,
    room (the proxy box: ``reference.box`` where given, else the environment's bounds)."""
    box = scene.reference.box or tuple(tuple(map(float, b)) for b in scene.bounds())
    return {"reference": tuple(map(float, scene.reference.point)), "room": box}


def capture_views(
    scene: Scene,
    methods: list[Method],
    imp: Impostor,
    B,
    *,
    cache: Cache,
    tracer: Tracer,
    background: np.ndarray | None = None,
) -> Captured:
    """What ``methods`` search, captured for ``scene``: the impostor ``imp`` on backend ``B``, the views their
    :meth:`~study.methods.base.Method.views_needed` ask for (depth layers, probe sets, the camera's buffer, whose
    colour is ``background``: the camera's render without the object, rendered here when not given) and the scene
    knowledge; a method asking for a view that is missing is then an error, not a fallback."""
    o = np.asarray(scene.reference.point, float)
    views = Views.merge(*(m.views_needed() for m in methods))
    layers, probe_sets, scr = (), {}, None
    if views.layers > 1:  # depth layers for the methods that search them
        tex = layered_impostor(scene, cache, views.layers, imp.radiance, tracer)
        layers = tuple(EnvMap(t, B) for t in tex)
    for spec in views.probes:  # cube maps at several points (probe 0: the impostor)
        texels, centres = probes.capture_probes(scene, spec, cache, imp.texels(), tracer)
        probe_sets[spec] = probes.ProbeSet.around(texels, centres, o, B)
    if views.screen:  # the camera's depth + colour (no object)
        if background is None:
            background = camera_render(scene, cache, with_object=False)
        scr = screen.ScreenView.of_scene(scene, background, tracer, B)
    return Captured(
        impostor=EnvMap(imp.texels(), B),
        layers=layers,
        probes=probe_sets,
        screen=scr,
        open=open_environment(imp),
        **env_info(scene),
    )


def open_environment(imp: Impostor) -> bool:
    """Whether some texels of the impostor see no surface (distance FAR: an open environment)."""
    return bool(np.any(imp.distance >= FAR_MIN))


def checked_lookups(m: Method, spent: np.ndarray, res: int) -> tuple[float, float]:
    """(mean, bound) of the lookups the rays of one trace spent; a ray over ``m.lookups_per_ray(res)`` is an
    error of the method (its bound is what budgets and floors count)."""
    bound = m.lookup_bound(res)
    spent = np.asarray(spent, np.float64)
    if spent.size and not spent.max() <= bound * (1 + 1e-6):
        raise StudyError(
            f"method {m.name!r} spent {spent.max():g} lookups on a ray, over its lookups_per_ray({res}) = "
            f"{bound:g}",
            key="method",
        )
    return (float(spent.mean()) if spent.size else 0.0), bound


def knob_columns(m: Method) -> dict:
    """The columns that place a method on its cost/accuracy curve: family (label without the knob), knob (the
    parameter's name, '' without one) and knob_value (NaN without one)."""
    return {
        "family": m.family(),
        "knob": m.knob.param if m.knob else "",
        "knob_value": float(m.knob_value) if m.knob else np.nan,
    }


# ---------------------------------------------------------------------------------------------- the case
def run_case(
    scene: Scene,
    methods: list[Method],
    *,
    backend: str = "numpy",
    cache: Cache | None = None,
    case_id: str = "",
    keep_images: bool = True,
) -> CaseOutput:
    cache = cache or Cache(None)
    B = backends.get(backend)
    tracer = make_tracer(scene.mesh())
    rays = shading.object_rays(
        scene, occluder=tracer.distance
    )  # a case that would be empty is refused before rendering
    if int(rays.full.sum()) < 4:  # too few object pixels: every image metric would be NaN
        raise StudyError(
            f"the camera sees {int(rays.full.sum())} pixel(s) fully on the object, at least 4 are "
            "needed; move object.center into view, closer, or turn camera.target towards it (or raise "
            "camera.width/height)",
            key="object.center",
        )
    o = np.asarray(scene.reference.point, float)

    # ------------------------------------------------------------------ inputs: impostor, renders, rays
    imp = impostor(scene, cache, tracer)
    background = camera_render(scene, cache, with_object=False)
    seeds = [
        camera_render(sc, cache, with_object=True)  # Mitsuba with the object, two seeds
        for sc in (scene, scene.with_updates({"render.seed": scene.render.seed + truth.SEED_OFFSET}))
    ]
    for what, img in (
        ("impostor radiance", imp.radiance),
        ("camera render", background),
        ("render", seeds[0]),
        ("render", seeds[1]),
    ):  # float32 overflow would still give plausible metrics
        if not np.isfinite(img).all():
            raise StudyError(
                f"the {what} is not finite (Mitsuba's float32 radiance overflows); lower "
                f"light.intensity (now {max(scene.light.intensity):g})",
                key="light.intensity",
            )
    mitsuba = (seeds[0] + seeds[1]) / 2
    F = shading.fresnel(scene, rays)
    mask = rays.full

    # ------------------------------------------------------------------ exact references: Embree and oracle
    ex_o, ex_d = rays.exact_rays()  # dielectrics: the exactly traced rays
    exact = tracer.intersect(ex_o, ex_d)["point"]
    escapes = ~np.all(np.isfinite(exact), axis=-1)  # open environments: the ray leaves the scene
    exact[escapes] = ex_o[escapes] + ex_d[escapes] * FAR  # "no surface": at infinity (cubemap.FAR)
    to_hit = exact - o
    hit_dist = np.linalg.norm(to_hit, axis=-1)
    seen = tracer.distance(np.broadcast_to(o, to_hit.shape), to_hit / hit_dist[:, None])
    occluded = seen < hit_dist * (1 - 1e-4) - 1e-5  # the exact hit is hidden from o
    nb = backends.get("numpy")
    env_np = EnvMap(imp.texels(), nb)
    oracle_rad = np.stack([np.asarray(c) for c in env_np.lookup(nb.vec(to_hit))[:3]], -1)
    oracle_img = shading.composite(rays, oracle_rad * F, background)  # oracle_map: what the map holds
    ref = truth.build(scene, cache, rays, F, background, seeds)  # truth_at_hit and the noise images
    visible = mask & (rays.per_pixel(occluded.astype(float), fill=1.0) == 0)  # pixels whose hits o sees
    sigma = truth.noise_rms(ref.noise, mask)  # the truth's own noise (debiased columns)

    against = scene.render.flip_against  # the references FLIP is measured against (the others: NaN)

    def image_columns(
        img, reference=False, fmap=None
    ):  # one image against every reference (fmap: its FLIP map)
        cols = {
            **metrics.image_errors(
                oracle_img, img, mask=mask, suffix="oracle", backend=backend, with_flip="oracle" in against
            ),
            **metrics.image_errors(
                ref.image,
                img,
                mask=mask,
                suffix="truth",
                flip_emap=fmap,
                backend=backend,
                with_flip="truth" in against,
            ),
            **metrics.image_errors(
                mitsuba, img, mask=mask, suffix="mitsuba", backend=backend, with_flip="mitsuba" in against
            ),
            **truth.columns(img, oracle_img, ref, mitsuba, mask=mask, visible=visible),
            **stats.pixel_columns(  # intervals over pixels, robust variants
                img, ref.image, mask=mask, sigma=sigma, rel_eps=truth.REL_EPS, emap=fmap
            ),
        }
        if reference:  # the truth is not split against itself
            cols.update({k: np.nan for k in cols if k.startswith("dec_")})
        return cols

    base = {
        "case": case_id,
        "cube_res": scene.render.cube_res,
        "object_x": scene.object.center[0],
        "object_y": scene.object.center[1],
        "object_z": scene.object.center[2],
        "backend": backend,
        "displacement": float(
            np.linalg.norm(np.subtract(scene.object.center, o)) / np.linalg.norm(np.subtract(*scene.bounds()))
        ),
        "rays": len(rays.x),
        "occluded_fraction": float(occluded.mean()) if len(occluded) else np.nan,
        **rays.stats,
    }
    out = CaseOutput(
        scene,
        [],
        oracle=oracle_img,
        mitsuba=mitsuba,
        truth=ref.image,
        mask=mask,
        occluded=rays.per_pixel(occluded.astype(float), fill=0.0),
    )
    eps = outcomes.tolerance(o, exact, scene.render.cube_res)  # per ray: max(1 cm, one texel at the hit)

    def classify(shown):  # outcome classes against the exact hits, on the methods' backend
        if backend == "numpy":
            return outcomes.classify(rays.x, rays.R, shown, exact, eps=eps, exact_origin=rays.exact_x)
        return outcomes.classify_on(B, rays.x, rays.R, shown, exact, eps=eps, exact_origin=rays.exact_x)

    for name, img in (
        ("oracle_map", oracle_img),
        ("truth_at_hit", ref.image),
    ):  # the exact hit, two radiances
        out.rows.append(
            {
                **base,
                "method": name,
                "label": name,
                "family": name,
                "knob": "",
                "knob_value": np.nan,
                **metrics.value_stats(np.zeros(len(rays.x)), "angle", "_deg"),
                "dist_median": 0.0,
                **outcomes.outcome_columns(classify(exact), occluded, np.zeros(len(rays.x))),  # correct
                **stats.ray_columns(classify(exact), np.zeros(len(rays.x)), occluded, rays.x, exact),
                **outcomes.offscreen_columns(classify(exact), outcomes.off_screen(scene.camera, exact)),
                **image_columns(img, reference=name == "truth_at_hit"),
                "valid_fraction": 1.0,
                "ratio_residual_median": 0.0,
                "lookups_per_ray": 1 if name == "oracle_map" else 0,
                "lookups_bound": 1 if name == "oracle_map" else 0,
                "seconds": 0.0,
            }
        )

    # ------------------------------------------------------------------ every method on the same rays
    env = capture_views(scene, methods, imp, B, cache=cache, tracer=tracer, background=background)
    offscreen = outcomes.off_screen(scene.camera, exact)  # exact hits the camera's frame does not show
    x, R = B.vec(rays.x - o), B.vec(rays.R)
    for m in methods:
        t0 = time.perf_counter()
        with np.errstate(divide="ignore", invalid="ignore"):  # numpy evaluates both sides of every select
            tr = m.trace(B, env, x, R)
        B.eval(
            tr.shown.x,
            tr.shown.y,
            tr.shown.z,
            tr.radiance.x,
            tr.radiance.y,
            tr.radiance.z,
            tr.ratio,
            tr.valid,
            tr.lookups,
        )  # one kernel for all outputs, not one per numpy copy
        shown = B.to_numpy(tr.shown).astype(np.float64) + o
        rad = B.to_numpy(tr.radiance).astype(np.float64)
        ratio, valid = B.numpy(tr.ratio), B.numpy(tr.valid).astype(bool)
        seconds = time.perf_counter() - t0
        lookups, bound = checked_lookups(m, B.numpy(tr.lookups), scene.render.cube_res)
        if not np.isfinite(shown[valid]).all():
            raise StudyError(
                f"method {m.name!r} returned {int((~np.isfinite(shown[valid])).any(-1).sum())} non-finite "
                "point(s) on rays it marked valid (NaN or inf)",
                key="method",
            )
        img = shading.composite(rays, np.nan_to_num(rad) * F, background)
        ang = metrics.angular_error(rays.x, shown, exact)
        oc = classify(shown)
        fmap = metrics.flip_map(ref.image, img, backend) if keep_images else None
        row = {
            **base,
            "method": m.name,
            "label": m.label,
            **knob_columns(m),
            **metrics.value_stats(ang, "angle", "_deg"),
            "dist_median": float(np.nanmedian(np.linalg.norm(shown - exact, axis=-1))),
            **outcomes.outcome_columns(oc, occluded, ang),
            **stats.ray_columns(oc, ang, occluded, rays.x, exact),  # counts, intervals, fixed tolerances
            **outcomes.offscreen_columns(oc, offscreen),
            **image_columns(img, fmap=fmap),
            "valid_fraction": float(valid.mean()),
            "ratio_residual_median": float(np.nanmedian(np.abs(ratio - 1))),
            "lookups_per_ray": lookups,
            "lookups_bound": bound,
            "seconds": seconds,
        }
        out.rows.append(row)
        if keep_images:
            out.images[m.label] = img
            out.angle_maps[m.label] = rays.per_pixel(ang, fill=np.nan)
            out.flip_maps[m.label] = fmap
            out.outcome_maps[m.label] = outcomes.majority(
                rays.per_pixel(outcomes.class_fractions(oc), fill=np.nan)
            )
    return out
