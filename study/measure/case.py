"""One case end to end: capture → shade the object with each method → references → metrics.

A reader can follow one ray here: camera ray → object (``shading.object_rays``) → reflected ray (x, R) →
``method.trace`` on the chosen backend → shown point and radiance → Fresnel → composited image; the same ray →
Embree exact hit → outcome class and angular error; the images → image error against the oracle_map, the
truth_at_hit and Mitsuba (:mod:`study.measure.truth`), and the error split over every object pixel
(:mod:`study.measure.split`, which also defines the oracle).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from study import backend as backends
from study import progress
from study.cache import Cache
from study.errors import StudyError
from study.impostor.cubemap import FAR
from study.impostor.envmap import EnvMap
from study.impostor.views import Lobe
from study.measure import metrics, outcomes, split, stats, truth
from study.measure.inputs import camera_render, capture_views, impostor, second_captures
from study.methods import Method
from study.optics import shading
from study.reference.tracer import make_tracer
from study.scene import Scene


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
    oracle: np.ndarray | None = None  # (H, W, 3) oracle_map (study.measure.split; unheld pixels marked)
    held: np.ndarray | None = None  # (H, W) pixels whose every hit o's views hold (the oracle's pixels)
    mitsuba: np.ndarray | None = None  # (H, W, 3) Mitsuba's render with the object (2 seeds)
    truth: np.ndarray | None = None  # (H, W, 3) truth_at_hit composited (study.measure.truth)
    occluded: np.ndarray | None = None  # (H, W) fraction of sub-pixel rays occluded from o
    mask: np.ndarray | None = None  # (H, W) pixels fully on the object


# ---------------------------------------------------------------------------------------------- cached inputs
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
    mark = progress.Stages()  # load, capture, probes, references, methods, metrics (study.progress)
    mark("load")
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

    # ------------------------------------------------------------------ inputs: impostor, renders, views
    mark("capture")
    imp = impostor(scene, cache, tracer)
    background = camera_render(scene, cache, with_object=False)
    for what, img in (("impostor radiance", imp.radiance), ("camera render", background)):
        _finite(scene, what, img)
    mark("probes")
    lobe = Lobe(scene.object.alpha, B.vec(rays.N)) if rays.src is None else None  # glossy: conductors only
    env = capture_views(scene, methods, imp, B, cache=cache, tracer=tracer, background=background, lobe=lobe)

    # ------------------------------------------------------------------ exact references: Mitsuba, Embree, oracle
    mark("references")
    seeds = [
        camera_render(sc, cache, with_object=True)  # Mitsuba with the object, two seeds
        for sc in (scene, scene.with_updates({"render.seed": scene.render.seed + truth.SEED_OFFSET}))
    ]
    for img in seeds:
        _finite(scene, "render", img)
    mitsuba = (seeds[0] + seeds[1]) / 2
    F = shading.fresnel(scene, rays)
    mask = rays.full
    ex_o, ex_d = rays.exact_rays()  # dielectrics: the exactly traced rays
    exact = tracer.intersect(ex_o, ex_d)["point"]
    escapes = ~np.all(np.isfinite(exact), axis=-1)  # open environments: the ray leaves the scene
    exact[escapes] = ex_o[escapes] + ex_d[escapes] * FAR  # "no surface": at infinity (cubemap.FAR)
    to_hit = exact - o
    hit_dist = np.linalg.norm(to_hit, axis=-1)
    seen = tracer.distance(np.broadcast_to(o, to_hit.shape), to_hit / hit_dist[:, None])
    occluded = seen < hit_dist * (1 - 1e-4) - 1e-5  # the exact hit is hidden from o
    nb = backends.get("numpy")
    ref = truth.build(scene, cache, rays, F, background, seeds)  # truth_at_hit and the noise images
    held = split.held(occluded, escapes)  # hits o's views hold: seen from o, or escaping to the background

    def oracle_of(env):  # oracle_map from one capture (split.oracle_radiance)
        looked = np.stack([np.asarray(c) for c in env.lookup(nb.vec(to_hit))[:3]], -1)
        rad = split.oracle_radiance(looked, ref.along, held, escapes)
        return shading.composite(rays, np.nan_to_num(rad) * F, background)

    held_px = split.held_pixels(rays, held)
    oracle_img = split.mark(oracle_of(EnvMap(imp.texels(), nb)), held_px | ~mask)  # unheld pixels: MARK
    oracle_seed, oracle_coarse = (oracle_of(EnvMap(t, nb)) for t in second_captures(scene, cache, imp))
    on_held = mask & held_px  # the pixels whose every hit the views hold: where the oracle has a value
    sigma = truth.noise_rms(ref.noise, mask)  # the truth's own noise (debiased columns)

    against = scene.render.flip_against  # the references FLIP is measured against (the others: NaN)

    def image_columns(img, reference=False, fmap=None, over=mask):  # one image against every reference
        cols = {
            **metrics.image_errors(  # on held pixels; unheld ones take img's value (FLIP and SSIM filter
                np.where((held_px | ~mask)[..., None], oracle_img, img),
                img,
                mask=on_held,
                suffix="oracle",
                backend=backend,
                with_flip="oracle" in against,
            ),  # across pixels: a marked neighbour must not count); fmap: its FLIP map
            **metrics.image_errors(
                ref.image,
                img,
                mask=over,
                suffix="truth",
                flip_emap=fmap,
                backend=backend,
                with_flip="truth" in against,
            ),
            **metrics.image_errors(
                mitsuba, img, mask=over, suffix="mitsuba", backend=backend, with_flip="mitsuba" in against
            ),
            **truth.columns(img, ref, mitsuba, mask=over),
            **stats.pixel_columns(  # intervals over pixels, robust variants
                img, ref.image, mask=over, sigma=sigma, rel_eps=truth.REL_EPS, emap=fmap
            ),
            **split.split_columns(
                img,
                ref.image,
                ref.noise,
                oracle_img,
                oracle_seed,
                oracle_coarse,
                mask=over,
                held_px=held_px,
                intervals=keep_images,  # figures: with intervals; sweeps: the values only
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
        **({"object_alpha": scene.object.alpha} if scene.object.alpha > 0 else {}),  # rough objects only
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
        held=held_px,
        occluded=rays.per_pixel(occluded.astype(float), fill=0.0),
    )
    eps = outcomes.tolerance(o, exact, scene.render.cube_res)  # per ray: max(1 cm, one texel at the hit)

    def classify(shown):  # outcome classes against the exact hits, on the methods' backend
        if backend == "numpy":
            return outcomes.classify(rays.x, rays.R, shown, exact, eps=eps, exact_origin=rays.exact_x)
        return outcomes.classify_on(B, rays.x, rays.R, shown, exact, eps=eps, exact_origin=rays.exact_x)

    # ------------------------------------------------------------------ every method on the same rays
    mark("methods")
    offscreen = outcomes.off_screen(scene.camera, exact)  # exact hits the camera's frame does not show
    x, R = B.vec(rays.x - o), B.vec(rays.R)
    traced = []
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
        traced.append((m, shown, rad, ratio, valid, seconds, lookups, bound))

    # ------------------------------------------------------------------ metrics: references' rows, then methods'
    mark("metrics")
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
                **image_columns(  # the oracle over the pixels it holds
                    img, reference=name == "truth_at_hit", over=on_held if name == "oracle_map" else mask
                ),
                "held_fraction": float(held.mean()) if len(held) else np.nan,
                "valid_fraction": 1.0,
                "ratio_residual_median": 0.0,
                "lookups_per_ray": 1 if name == "oracle_map" else 0,
                "lookups_bound": 1 if name == "oracle_map" else 0,
                "seconds": 0.0,
            }
        )
    for m, shown, rad, ratio, valid, seconds, lookups, bound in traced:
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
    mark.end()
    return out


#: A light this strong can overflow Mitsuba's float32 radiance (3.4e38) in a render; a weaker one cannot.
OVERFLOWING_INTENSITY = 1e30


def _finite(scene: Scene, what: str, img: np.ndarray) -> None:
    """Refuse a render that is not finite: float32 overflow would still give plausible metrics. The light is
    blamed only where it is strong enough to overflow; else the environment, whose file or plug-in brought the
    non-finite value (colours, textures and emissions are checked when it is built: here whatever is left)."""
    if np.isfinite(img).all():
        return
    intensity = max(scene.light.intensity)
    if intensity >= OVERFLOWING_INTENSITY:
        raise StudyError(
            f"the {what} is not finite (Mitsuba's float32 radiance overflows); lower "
            f"light.intensity (now {intensity:g})",
            key="light.intensity",
        )
    raise StudyError(
        f"the {what} is not finite ({int((~np.isfinite(img)).any(-1).sum())} pixel(s) NaN or inf) with a light "
        f"of intensity {intensity:g}, which cannot overflow: a non-finite value in the environment "
        f"({scene.environment.label()}): a colour, texture or emission of its file",
        key="environment",
    )
