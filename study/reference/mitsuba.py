"""Mitsuba 3 renders of a :class:`~study.scene.Scene`: the ground truth and the impostor's radiance.

The environment is built from :func:`study.scene.environment.geometry` (the very triangles Embree intersects): the
box room's surfaces with their procedural textures, a mesh file's parts with their textures or colours (two-sided
diffuse BSDFs), or a Mitsuba scene's own shapes, BSDFs and emitters; box and mesh environments get the point
light; the sky the user gives (``environment.sky``, :mod:`study.scene.sky`) replaces the file's environment
emitter; the object is a Mitsuba sphere with
its real material (``conductor`` with per-channel eta and k, a perfect mirror, or a ``dielectric``), or a mesh with
smooth vertex normals for mesh shapes. A dielectric object gets ``max_depth + 2`` (in and out of the glass).
Rendering uses the
``llvm_ad_rgb`` variant on the CPU (``cuda_ad_rgb`` on a GPU) and the ``path`` integrator.
"""

from __future__ import annotations

import numpy as np

from study import progress, runtime
from study.scene import Scene, sky
from study.scene.environment import geometry
from study.scene.objects import object_mesh as make_object_mesh


def mi(variant: str | None = None):
    """The mitsuba module with ``variant`` set, by default the render device's (:func:`study.runtime.mitsuba`)."""
    return runtime.mitsuba(variant)


def triangle_mesh(m, name, V, F, UV, bsdf, colors=None, emission=None):
    """A Mitsuba mesh of triangles (V, F) with texture coordinates UV, a loaded BSDF and, optionally, per-vertex
    ``colors`` (V, 3) as the attribute ``vertex_color`` and an ``area`` emitter of radiance ``emission`` (linear
    RGB, W/(m² sr), emitted on the side the counter-clockwise winding faces)."""
    props = m.Properties()
    props["bsdf"] = bsdf
    if emission is not None:
        props["emitter"] = m.load_dict({"type": "area", "radiance": {"type": "rgb", "value": list(emission)}})
    mesh = m.Mesh(name, len(V), len(F), props=props, has_vertex_texcoords=True)
    if colors is not None:
        mesh.add_attribute("vertex_color", 3, np.ascontiguousarray(colors, np.float32).ravel())
    p = m.traverse(mesh)
    p["vertex_positions"] = np.ascontiguousarray(V, np.float32).ravel()
    p["faces"] = np.ascontiguousarray(F, np.uint32).ravel()
    p["vertex_texcoords"] = np.ascontiguousarray(UV, np.float32).ravel()
    p.update()
    return mesh


def part_bsdf(m, part) -> object:
    """A two-sided diffuse BSDF from a surface's texture, constant colour or vertex colours."""
    if part.albedo is not None:
        refl = {"type": "bitmap", "bitmap": m.Bitmap(part.albedo), "raw": True, "filter_type": "bilinear"}
    elif part.vertex_colors:
        refl = {"type": "mesh_attribute", "name": "vertex_color"}
    else:
        refl = {"type": "rgb", "value": list(map(float, part.color))}
    return m.load_dict({"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": refl}})


def punctual(m, li: dict) -> dict:
    """A Mitsuba emitter dict of a mesh file's punctual light (:mod:`study.scene.parts`: radiometric, world)."""
    rgb = lambda v: {"type": "rgb", "value": [float(x) for x in v]}  # noqa: E731
    if li["type"] == "point":
        return {"type": "point", "position": li["position"], "intensity": rgb(li["intensity"])}
    if li["type"] == "directional":
        return {"type": "directional", "direction": li["direction"], "irradiance": rgb(li["irradiance"])}
    p, d = np.asarray(li["position"], float), np.asarray(li["direction"], float)
    up = [0.0, 1.0, 0.0] if abs(d[1]) < 0.99 else [1.0, 0.0, 0.0]
    return {
        "type": "spot",
        "to_world": m.ScalarTransform4f().look_at(origin=p.tolist(), target=(p + d).tolist(), up=up),
        "intensity": rgb(li["intensity"]),
        "cutoff_angle": li["cutoff_angle"],
        "beam_width": min(li["beam_width"], li["cutoff_angle"]),
    }


def object_bsdf(scene: Scene) -> dict:
    """The object's BSDF: ``conductor`` / ``dielectric`` when smooth, ``roughconductor`` / ``roughdielectric``
    with GGX ``alpha`` = ``object.alpha`` when α > 0."""
    bsdf = _smooth_bsdf(scene)
    alpha = scene.object.alpha
    if alpha > 0:
        bsdf = {**bsdf, "type": "rough" + bsdf["type"], "distribution": "ggx", "alpha": float(alpha)}
    return bsdf


def _smooth_bsdf(scene: Scene) -> dict:
    mat = scene.object.material
    if mat.type == "mirror":
        return {"type": "conductor", "material": "none"}
    if mat.type == "dielectric":
        return {"type": "dielectric", "int_ior": mat.ior, "ext_ior": 1.0}
    return {
        "type": "conductor",
        "eta": {"type": "rgb", "value": list(mat.n)},
        "k": {"type": "rgb", "value": list(mat.k)},
    }


def scene_dict(scene: Scene, *, with_object: bool, sensor: dict, integrator: dict | None = None) -> dict:
    """The Mitsuba scene dict of ``scene``: its environment (:func:`study.scene.environment.geometry`: the box
    room's textured surfaces, a mesh file's parts, or a Mitsuba scene's own shapes and emitters), the point light
    where the environment uses ``[light]``, ``sensor``, the ``path`` integrator and, ``with_object``, the object."""
    m = mi()
    env = geometry(scene)
    depth = scene.render.max_depth
    if with_object and scene.object.material.type == "dielectric":
        depth += 2  # entering and leaving the glass: the room behind gets max_depth as well
    d = {"type": "scene", "sensor": sensor, "integrator": integrator or {"type": "path", "max_depth": depth}}
    if scene.lamp():
        d["light"] = {
            "type": "point",
            "position": list(scene.light.position),
            "intensity": {"type": "rgb", "value": list(scene.light.intensity)},
        }
    given = scene.environment.sky is not None  # the user's sky replaces the file's own (one per scene)
    for i, e in enumerate(
        env.emitters
    ):  # a Mitsuba scene's own emitters (area lights come with their shapes)
        if not (given and m.has_flag(e.flags(), m.EmitterFlags.Infinite)):
            d[f"emitter_{i}"] = e
    if sky.emitter(scene.environment.sky) is not None:  # what escaping rays see (study.scene.sky)
        d["sky"] = sky.emitter(scene.environment.sky)
    for i, li in enumerate(env.lights):  # a mesh file's punctual lights
        d[f"file_light_{i}"] = punctual(m, li)
    mesh = env.mesh
    for sid, part in enumerate(env.parts):
        if not np.any(mesh.surface == sid):
            continue
        if part.native is not None:  # a Mitsuba scene's shape, with its BSDF and area light
            d[f"surface_{sid}"] = part.native
            continue
        V, F, UV = mesh.part(sid)
        d[f"surface_{sid}"] = triangle_mesh(
            m,
            part.name,
            V,
            F,
            UV,
            part_bsdf(m, part),
            colors=mesh.part_colors(sid) if part.vertex_colors else None,
            emission=part.emission,
        )
    if with_object and scene.object.shape == "sphere":
        d["object"] = {
            "type": "sphere",
            "center": list(scene.object.center),
            "radius": scene.object.radius,
            "bsdf": object_bsdf(scene),
        }
    elif with_object:
        d["object"] = object_shape_dict(scene)
    return d


def object_shape_dict(scene: Scene):
    """The object's triangles (:func:`study.scene.objects.object_mesh`, the ones Embree intersects) with their smooth
    vertex normals, as a Mitsuba mesh with the object's BSDF."""
    m = mi()
    om = make_object_mesh(scene.object)
    props = m.Properties()
    props["bsdf"] = m.load_dict(object_bsdf(scene))
    mesh = m.Mesh("object", len(om.vertices), len(om.faces), props=props, has_vertex_normals=True)
    p = m.traverse(mesh)
    p["vertex_positions"] = np.ascontiguousarray(om.vertices, np.float32).ravel()
    p["faces"] = np.ascontiguousarray(om.faces, np.uint32).ravel()
    p["vertex_normals"] = np.ascontiguousarray(om.normals, np.float32).ravel()
    p.update()
    return mesh


def sensor(origin, target, up, fov, width, height, spp, seed, *, jitter=True) -> dict:
    m = mi()
    sampler = (
        {"type": "independent", "sample_count": spp, "seed": seed}
        if jitter
        else {"type": "stratified", "sample_count": 1, "jitter": False, "seed": seed}
    )
    return {
        "type": "perspective",
        "fov": fov,
        "fov_axis": "x",
        "near_clip": 1e-4,
        "to_world": m.ScalarTransform4f().look_at(
            origin=list(map(float, origin)), target=list(map(float, target)), up=list(map(float, up))
        ),
        "film": {
            "type": "hdrfilm",
            "width": width,
            "height": height,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
        "sampler": sampler,
    }


@progress.rendering  # its time: the case's Mitsuba renders (study.progress)
def render_camera(scene: Scene, *, with_object: bool = True, spp: int | None = None) -> np.ndarray:
    """The camera's view, path traced: (H, W, 3) float32 linear RGB."""
    m = mi()
    c = scene.camera
    cam = sensor(c.eye, c.target, c.up, c.fov, c.width, c.height, spp or scene.render.spp, scene.render.seed)
    sc = m.load_dict(scene_dict(scene, with_object=with_object, sensor=cam))
    return np.array(m.render(sc, seed=scene.render.seed), dtype=np.float32)


def triangle_scene(V: np.ndarray, F: np.ndarray, variant: str | None = None):
    """(mitsuba module, scene) holding the triangles (V, F) as one diffuse mesh, in ``variant``: for ray queries."""
    m = mi(variant)
    mesh = triangle_mesh(m, "room", V, F, np.zeros((len(V), 2), np.float32), m.load_dict({"type": "diffuse"}))
    return m, m.load_dict({"type": "scene", "room": mesh})


@progress.rendering  # its time: the case's Mitsuba renders (study.progress)
def radiance_along(
    scene: Scene,
    origins: np.ndarray,
    dirs: np.ndarray,
    *,
    spp: int,
    seed: int = 0,
    max_depth: int | None = None,
    chunk: int = 1 << 20,
) -> np.ndarray:
    """Radiance arriving at ``origins`` along −``dirs`` (what a ray o + t d sees), path traced by Mitsuba in the
    scene without the object: (N, 3) float32, the mean of ``spp`` samples per ray.

    The scene's ``path`` integrator with ``max_depth`` (default ``render.max_depth``) counted from the ray's origin,
    as for the impostor's faces captured from the reference point: a ray leaving the object gets the same bounce
    budget as the impostor. Each sample is ``integrator.sample`` on the ray itself (independent sampler)."""
    m = mi()
    o = np.asarray(scene.reference.point, float)
    integrator = {"type": "path", "max_depth": max_depth or scene.render.max_depth}
    sc = m.load_dict(
        scene_dict(
            scene,
            with_object=False,
            integrator=integrator,
            sensor=sensor(o, o + [0, 0, 1], [0, 1, 0], 90.0, 8, 8, 1, seed),
        )
    )
    integ = sc.integrator()
    out = np.zeros((len(origins), 3), np.float32)
    per = max(1, chunk // spp)
    for s in range(0, len(origins), per):
        org = np.repeat(np.asarray(origins[s : s + per], np.float32), spp, axis=0)
        d = np.repeat(np.asarray(dirs[s : s + per], np.float32), spp, axis=0)
        sampler = m.load_dict({"type": "independent"})
        sampler.seed(seed + s, len(org))
        ray = m.Ray3f(m.Point3f(*org.T), m.Vector3f(*d.T))
        rgb, _, _ = integ.sample(sc, sampler, ray)
        out[s : s + per] = np.array(rgb, np.float32).T.reshape(-1, spp, 3).mean(1)
    return out
