"""What a case measures with, before any method runs: the captured impostor (cached), Mitsuba's camera renders
(cached), the views the methods ask for (layers, probes, screen, distance fields, the prefiltered chain: a
:class:`~study.impostor.views.Captured`) and the oracle's second captures (another seed, half the resolution)."""

from __future__ import annotations

import numpy as np

from study.cache import Cache, content_key
from study.errors import StudyError
from study.impostor import hitcache, prefilter, probes, screen
from study.impostor.capture import Impostor, capture_distance, impostor_key, render_cube
from study.impostor.cubemap import FAR_MIN
from study.impostor.envmap import EnvMap
from study.impostor.layers import layered_impostor
from study.impostor.sdf import SdfGrid, sdf_grid
from study.impostor.views import Captured, Lobe, Views
from study.measure import split, truth
from study.methods import Method
from study.reference.embree import Tracer
from study.reference.mitsuba import radiance_along, render_camera
from study.scene import Scene
from study.scene.environment import env_key
from study.scene.sources import key_fields


def distance_key(scene: Scene) -> str:
    """Content key of the impostor's distances: the environment's triangles, the reference point and the cube
    resolution, nothing path traced (:func:`study.impostor.capture.capture_distance` is Embree's exact distances):
    not the seed, the samples, the bounces or the light, so the seeds of one geometry read one capture."""
    return content_key(env_key(scene), [float(c) for c in scene.reference.point], scene.render.cube_res,
                       "distance-v1")  # fmt: skip


def impostor(scene: Scene, cache: Cache, tracer: Tracer | None = None) -> Impostor:
    """The impostor of ``scene``, cached: its radiance (path traced: one per seed, :func:`impostor_key`) and its
    distances (exact: one per geometry, :func:`distance_key`)."""
    r = scene.render
    key = impostor_key(scene)
    rad = cache.get("radiance", key, lambda: render_cube(scene, r.cube_res, r.cube_spp), code=render_cube)
    dist = cache.get(
        "distance", distance_key(scene), lambda: capture_distance(scene, r.cube_res, tracer),
        code=capture_distance,
    )  # fmt: skip
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


def prefiltered(scene: Scene, cache: Cache, imp: Impostor, B) -> prefilter.MipChain:
    """The impostor's GGX-prefiltered mip chain (:mod:`study.impostor.prefilter`), cached like the impostor (its
    key, the chain's settings and the code)."""
    r = scene.render
    sizes = [prefilter.level_res(r.cube_res, prefilter.level_alpha(m)) for m in range(prefilter.LEVELS)]
    key = content_key(impostor_key(scene), prefilter.LEVELS, prefilter.SAMPLES, "prefiltered-v1")
    flat = cache.get(
        "prefiltered",
        key,
        lambda: np.concatenate([t.ravel() for t in prefilter.prefilter(imp.texels())]),
        code=prefilter.prefilter,
    )
    ends = np.cumsum([6 * s * s * 4 for s in sizes])
    levels = [a.reshape(6, s, s, 4) for a, s in zip(np.split(flat, ends[:-1]), sizes)]
    return prefilter.MipChain(levels, B)


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
    lobe: Lobe | None = None,
    truth_along=None,
) -> Captured:
    """What ``methods`` search, captured for ``scene``: the impostor ``imp`` on backend ``B``, the views their
    :meth:`~study.methods.base.Method.views_needed` ask for (depth layers, probe sets, the camera's buffer, whose
    colour is ``background``: the camera's render without the object, rendered here when not given, the
    prefiltered impostor, the exact tracer's hits: ``tracer``) and the scene knowledge, with ``lobe`` (the rays'
    roughness and normals) and ``truth_along`` (a function () → the case's exact rays and truth_at_hit's radiance
    along them, which exact shading hands back on those rays: :func:`exact_shading`); a method asking for a view
    that is missing is then an error, not a fallback."""
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
    fields = {spec: SdfGrid(*sdf_grid(scene, spec, cache), o, B) for spec in views.sdfs}  # distance fields

    def shade(origins, dirs):  # exact shading (exact_shading): the truth's own values on its rays
        return exact_shading(scene, origins, dirs, truth_along)

    pre = prefiltered(scene, cache, imp, B) if views.prefiltered else None
    cached = hit_caches(scene, cache, tracer, views.caches) if views.caches else None
    return Captured(
        impostor=EnvMap(imp.texels(), B),
        layers=layers,
        probes=probe_sets,
        screen=scr,
        sdfs=fields,
        shade=shade if views.shade else None,
        hits=(lambda origins, dirs: tracer.intersect(origins, dirs)["point"]) if views.hits else None,
        cached=cached,
        open=open_environment(imp),
        prefiltered=pre,
        lobe=lobe,
        **env_info(scene),
    )


def exact_shading(scene: Scene, origins: np.ndarray, dirs: np.ndarray, truth_along=None) -> np.ndarray:
    """(N, 3) the radiance arriving along each ray (``Captured.shade``, world origins and directions), as the case's
    truth estimates it: on the case's own exact rays (``truth_along()`` = their origins, directions and
    truth_at_hit's two-seed mean, the same rays in the same order up to float32 rounding:
    :func:`study.measure.truth.same_rays`) truth_at_hit's own value, so a method that traces and shades those rays
    exactly (``traced``) shows the truth's image, not a second estimate of it with noise of its own; on any other
    ray path traced by Mitsuba, as the truth is, at ``render.spp`` with a seed of its own (not the truth's two: its
    noise is not shared). A rough object's truth is its lobe's average, not the radiance along the ray: every ray
    is then path traced."""
    o, d = np.asarray(origins, float), np.asarray(dirs, float)
    same = np.zeros(len(o), bool)
    if truth_along is not None and scene.object.alpha == 0 and len(o):
        ex_o, ex_d, along = truth_along()
        lo, hi = scene.bounds()
        same = truth.same_rays(ex_o, ex_d, o, d, float(np.linalg.norm(np.subtract(hi, lo))))
    out = np.zeros((len(o), 3), np.float32)
    if same.any():
        out[same] = along[same]
    if not same.all():
        seed = scene.render.seed + 2 * truth.SEED_OFFSET
        out[~same] = radiance_along(scene, o[~same], d[~same], spp=scene.render.spp, seed=seed)
    return out


def second_captures(scene: Scene, cache: Cache, imp: Impostor) -> tuple[np.ndarray, np.ndarray]:
    """The impostor's radiance once more, (6, R, R, 4) texels (distance channel 0, unused by the oracle): captured
    with a second seed (``render.seed + SEED_OFFSET``) and 1/:data:`~study.measure.split.SEED_SPP_DIVISOR` of the
    samples per texel (a fraction of the capture's cost), and at half the resolution (2 × 2 texel means of the
    map: the same as a capture at R/2 with four times the samples, texels being box-filtered pixel means). The
    representation term of :mod:`study.measure.split` is measured from them."""
    r = scene.render
    other = scene.with_updates({"render.seed": r.seed + truth.SEED_OFFSET})
    spp = max(1, r.cube_spp // split.SEED_SPP_DIVISOR)
    seed2 = cache.get(
        "radiance",
        impostor_key(other, spp=spp),
        lambda: render_cube(other, r.cube_res, spp),
        code=render_cube,
    ).reshape(6, r.cube_res, r.cube_res, 3)
    coarse = split.coarser(imp.radiance)
    return tuple(np.concatenate([c, np.zeros(c.shape[:-1] + (1,), c.dtype)], -1) for c in (seed2, coarse))


def open_environment(imp: Impostor) -> bool:
    """Whether some texels of the impostor see no surface (distance FAR: an open environment)."""
    return bool(np.any(imp.distance >= FAR_MIN))


def hit_caches(scene: Scene, cache: Cache, tracer, resolutions: tuple[int, ...]):
    """The hit-lighting caches at ``resolutions`` (:mod:`study.impostor.hitcache`), filled once from the same
    path-traced surface samples (cached: ``hitcache.FILL_SAMPLES`` points per side at ``render.spp``), as a function
    (res, origins, dirs) → the radiance each cache holds at the rays' exact hits (NaN on a miss of the scene).

    The fill is the scene's without the object, so its key is the environment's (:func:`fill_key`): every case of
    a sweep over the object, the camera, the reference point or the cube resolution reads one fill."""
    mesh = tracer.mesh
    key = fill_key(scene)
    seed = scene.render.seed + 3 * truth.SEED_OFFSET  # a stream of its own

    def samples():
        p, n = hitcache.surface_samples(mesh.vertices, mesh.faces, hitcache.FILL_SAMPLES, seed)
        L = radiance_along(scene, p + hitcache.FILL_OFFSET * n, -n, spp=scene.render.spp, seed=seed)
        return np.concatenate([p, n, np.asarray(L, float)], axis=1)

    pnl = cache.get("hit_cache", key, samples, code=(hitcache.surface_samples, radiance_along)).reshape(-1, 9)
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    grids = {}
    for res in resolutions:
        grids[res] = hitcache.GridCache.empty(lo, hi, res)
        grids[res].add(pnl[:, :3], pnl[:, 3:6], pnl[:, 6:])

    def read(res, origins, dirs):
        hit = tracer.intersect(origins, dirs)
        ok = hit["prim"] >= 0
        out = np.full((len(origins), 3), np.nan)
        if ok.any():
            nrm = hitcache.hit_normals(mesh.vertices, mesh.faces, hit["prim"][ok], np.asarray(dirs)[ok])
            out[ok] = grids[res].query(hit["point"][ok], nrm)[0]
        return out

    return read


def fill_key(scene: Scene) -> str:
    """Content key of the hit-lighting cache's fill: what radiance leaving the environment's surfaces depends on
    (the environment and its columns, the light, the path tracer's samples, bounces and seed), not the object,
    the camera, the reference point or the cube maps."""
    r = scene.render
    parts = {"environment": env_key(scene), "light": key_fields(scene.light), "lamp": scene.lamp(),
             "spp": r.spp, "max_depth": r.max_depth, "seed": r.seed}  # fmt: skip
    return content_key(parts, hitcache.FILL_SAMPLES, "hit-cache-samples-v2")


#: A light this strong can overflow Mitsuba's float32 radiance (3.4e38) in a render; a weaker one cannot.
OVERFLOWING_INTENSITY = 1e30


def finite(scene: Scene, what: str, *imgs: np.ndarray) -> None:
    """Refuse a render that is not finite: float32 overflow would still give plausible metrics. The light is
    blamed only where it is strong enough to overflow; else the environment, whose file or plug-in brought the
    non-finite value (colours, textures and emissions are checked when it is built: here whatever is left).
    ``imgs``: the renders called ``what`` (a case's camera renders, its impostor's radiance)."""
    img = next((i for i in imgs if not np.isfinite(i).all()), None)
    if img is None:
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
