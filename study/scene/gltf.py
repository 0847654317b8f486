"""glTF 2.0 (``.gltf`` + buffers, or ``.glb``), read as the specification defines it (not through trimesh).

* The document and its bytes come from :class:`study.scene.gltf_data.GltfFile`: types and indices checked before
  use, files kept inside the scene's folder, truncation refused, sparse accessors applied. Nodes are walked as the
  trees the spec says they are (a node reached twice, through a cycle or a second parent, is refused).
* Geometry: every node of the default scene (``scene``, else the first; other scenes counted as ignored) with its
  mesh, placed by the node's ``matrix`` or translation · rotation · scale, parents first; triangle lists, strips
  and fans (points and lines are ignored, counted); accessors of any component type (normalized integers scaled as
  the spec says), sparse accessors; a node whose transform mirrors (negative determinant) has its winding
  reversed. ``KHR_draco_mesh_compression`` is decoded by DracoPy
  (Google's decoder), the attributes taken by the unique ids the extension names.
* Materials: ``baseColorFactor`` and ``COLOR_0`` are linear; ``baseColorTexture`` is sRGB (converted, times the
  factor), its ``KHR_texture_transform`` (offset, rotation, scale, texCoord) applied to the uv (the rotation as
  Babylon.js, three.js, Blender and the sample model turn it: glTF issue #1563);
  ``emissiveFactor`` (linear) × ``KHR_materials_emissive_strength`` is the emitted radiance of an area light (an
  ``emissiveTexture`` contributes its mean, counted as ignored); transmission, alpha (``BLEND`` / ``MASK``), metal
  and other material extensions are not rendered (two-sided diffuse): counted as ignored. Colour factors outside
  [0, 1] and negative strengths are refused, naming the material.
* ``KHR_lights_punctual``: photometric → radiometric at 683 lm/W, the luminous efficacy at 555 nm that the
  Khronos exporters (Blender's among them) use both ways: point and spot ``intensity`` in candela (lm/sr) →
  W/sr = cd / 683 × ``color``; directional in lux (lm/m²) → W/m² = lx / 683 × ``color``. A spot's cone angles
  (radians, outer default π/4; 0 ≤ inner < outer ≤ π/2, as the spec says) become Mitsuba's ``cutoff_angle``
  (outer) and ``beam_width`` (inner), in degrees. Lights shine along the node's −z. ``range`` is ignored
  (counted): Mitsuba's lights fall off as 1/r². A negative intensity is refused, naming the light.
* ``EXT_meshopt_compression`` is decoded (:mod:`study.scene.gltf_data`); any other required extension that is
  not read is refused in one line.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from study.scene.gltf_data import GltfFile, is_index
from study.scene.parts import Loaded, Piece

LUMENS_PER_WATT = 683.0
COMPRESSION: dict[str, str] = {}  # compressions refused (none: Draco and meshopt are decoded)
READ = {
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_mesh_quantization",
    "KHR_texture_transform",
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
}


def _node_matrix(n: dict) -> np.ndarray:
    if "matrix" in n:
        return np.asarray(n["matrix"], float).reshape(4, 4).T  # column-major
    x, y, z, w = n.get("rotation", (0, 0, 0, 1))
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    M = np.eye(4)
    M[:3, :3] = R * np.asarray(n.get("scale", (1, 1, 1)), float)
    M[:3, 3] = n.get("translation", (0, 0, 0))
    return M


def _triangles(idx: np.ndarray, mode: int) -> np.ndarray:
    if mode == 4:
        return idx[: len(idx) // 3 * 3].reshape(-1, 3)
    k = np.arange(max(len(idx) - 2, 0))
    if mode == 5:  # strip: every other triangle reversed to keep the winding
        t = np.stack([idx[k], idx[k + 1], idx[k + 2]], 1)
        t[1::2] = t[1::2][:, [1, 0, 2]]
        return t
    return np.stack([np.full(len(k), idx[0] if len(idx) else 0), idx[k + 1], idx[k + 2]], 1)  # fan


def _check_extensions(f: GltfFile) -> None:
    used = set(f.g.get("extensionsUsed", [])) | set(f.g.get("extensionsRequired", []))
    for ext, what in COMPRESSION.items():
        if ext in used:
            f.fail(f"uses {ext} ({what}), which study cannot decode; re-export it uncompressed")
    other = sorted(set(f.g.get("extensionsRequired", [])) - READ)
    if other:
        f.fail(f"requires {', '.join(other)}, which study does not read")
    if str(f.g.get("asset", {}).get("version", "2.0")).split(".")[0] != "2":
        f.fail(f"glTF version {f.g['asset']['version']}; study reads glTF 2.0")


def _factor(f: GltfFile, v, n: int, default: tuple, what: str, hi: float | None = 1.0) -> np.ndarray:
    """A colour factor of ``n`` numbers in [0, hi] (glTF's schema), as floats; anything else is refused."""
    if v is None:
        v = default
    ok = isinstance(v, list | tuple) and len(v) == n and all(isinstance(x, int | float) for x in v)
    a = np.asarray(v, float) if ok else None
    if a is None or not np.isfinite(a).all() or (a < 0).any() or (hi is not None and (a > hi).any()):
        rng = f"[0, {hi:g}]" if hi is not None else "≥ 0"
        f.fail(f"{what} must be {n} number(s) in {rng} (glTF 2.0), got {v!r}")
    return a


def _uv_transform(t: dict) -> np.ndarray | None:
    """KHR_texture_transform as a 3 × 3 matrix on (u, v, 1): translation · rotation · scale (the spec's order)."""
    ext = t.get("extensions", {}).get("KHR_texture_transform")
    if not isinstance(ext, dict):
        return None
    (ox, oy), r, (sx, sy) = ext.get("offset", (0, 0)), ext.get("rotation", 0.0), ext.get("scale", (1, 1))
    c, s = np.cos(r), np.sin(r)
    T = np.array([[1, 0, ox], [0, 1, oy], [0, 0, 1]], float)
    R = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]], float)
    S = np.diag([sx, sy, 1.0])
    return T @ R @ S


def _material(f: GltfFile, i: int | None, out: Loaded, cache: dict, default: tuple) -> dict:
    """{"color", "texture", "texcoord", "uv_transform", "emission", "name"} of material ``i`` (counted once)."""
    if i in cache:
        return cache[i]
    if i is None:
        cache[i] = {"color": np.asarray(default, float), "texture": None, "texcoord": 0, "emission": None,
                    "uv_transform": None}  # fmt: skip
        return cache[i]
    m = f.get("materials", i, "a primitive's material")
    what = f"material {i} ({m.get('name') or 'unnamed'})"
    pbr, ext = m.get("pbrMetallicRoughness", {}), m.get("extensions", {})
    if not isinstance(pbr, dict) or not isinstance(ext, dict):
        f.fail(f"{what}: pbrMetallicRoughness and extensions must be objects")
    color = _factor(f, pbr.get("baseColorFactor"), 4, (1, 1, 1, 1), f"{what} baseColorFactor")[:3]  # linear
    tex, texcoord, uvt = None, 0, None
    if "baseColorTexture" in pbr:
        info = pbr["baseColorTexture"]
        t = f.get("textures", info.get("index"), f"{what} baseColorTexture")
        if "source" in t:
            tex = f.image(t["source"], f"texture {info.get('index')}") * color.astype(
                np.float32
            )  # sRGB × linear
            texcoord = info.get("texCoord", 0)
            uvt = _uv_transform(info)
            if uvt is not None:
                texcoord = info["extensions"]["KHR_texture_transform"].get("texCoord", texcoord)
            f.images_used.add(t["source"])
            out.textures = len(f.images_used)
    emission = _factor(f, m.get("emissiveFactor"), 3, (0, 0, 0), f"{what} emissiveFactor")
    strength = ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
    emission = emission * _factor(f, [strength], 1, (1,), f"{what} emissiveStrength", hi=None)[0]
    if "emissiveTexture" in m and emission.max() > 0:
        t = f.get("textures", m["emissiveTexture"].get("index"), f"{what} emissiveTexture")
        if "source" in t:
            emission = emission * f.image(t["source"], f"{what} emissiveTexture").reshape(-1, 3).mean(0)
            out.ignored["emissive texture (its mean used)"] += 1
    if m.get("alphaMode", "OPAQUE") != "OPAQUE":
        out.ignored["alpha"] += 1
    if ext.get("KHR_materials_transmission", {}).get("transmissionFactor", 0) > 0:
        out.ignored["transmission"] += 1
    if pbr.get("metallicFactor", 0) > 0 and "metallicFactor" in pbr:
        out.ignored["metallic"] += 1
    for name in sorted(set(ext) - {"KHR_materials_emissive_strength", "KHR_materials_transmission"}):
        out.ignored[name] += 1
    out.materials += 1
    cache[i] = {
        "color": color,
        "texture": tex,
        "texcoord": texcoord,
        "uv_transform": uvt,
        "emission": tuple(emission.tolist()) if emission.max() > 0 else None,
        "name": m.get("name") or f"material{i}",
    }
    return cache[i]


def _light(f: GltfFile, i, M: np.ndarray, out: Loaded) -> None:
    lights = f.g.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    if not isinstance(lights, list) or not is_index(i) or not 0 <= i < len(lights):
        f.fail(f"KHR_lights_punctual: light index {i!r} is out of range ({len(lights)} lights)")
    li = lights[i]
    what = f"KHR_lights_punctual light {i} ({li.get('name') or li.get('type')})"
    intensity = _factor(f, [li.get("intensity", 1.0)], 1, (1,), f"{what} intensity", hi=None)[0]
    rgb = _factor(f, li.get("color"), 3, (1, 1, 1), f"{what} color") * intensity / LUMENS_PER_WATT
    pos, d = M[:3, 3], M[:3, :3] @ np.array([0.0, 0.0, -1.0])
    d = d / (np.linalg.norm(d) or 1)
    if "range" in li:
        out.ignored["light range"] += 1
    kind = li.get("type")
    if kind == "point":
        out.lights.append({"type": "point", "position": pos.tolist(), "intensity": rgb.tolist()})
    elif kind == "spot":
        s = li.get("spot", {})
        inner, outer = s.get("innerConeAngle", 0.0), s.get("outerConeAngle", np.pi / 4)
        ok = all(isinstance(x, int | float) for x in (inner, outer))
        if not ok or not 0 <= inner < outer <= np.pi / 2 + 1e-9:
            f.fail(f"{what}: cone angles must satisfy 0 ≤ innerConeAngle < outerConeAngle ≤ π/2 (glTF), got "
                   f"{inner!r}, {outer!r}")  # fmt: skip
        out.lights.append(
            {
                "type": "spot",
                "position": pos.tolist(),
                "direction": d.tolist(),
                "intensity": rgb.tolist(),
                "cutoff_angle": float(np.degrees(outer)),
                "beam_width": float(np.degrees(inner)),
            }
        )
    elif kind == "directional":
        out.lights.append({"type": "directional", "direction": d.tolist(), "irradiance": rgb.tolist()})
    else:
        out.ignored[f"light of type {kind!r}"] += 1


def _camera(f: GltfFile, i, M: np.ndarray, out: Loaded) -> dict | None:
    """A perspective camera: at the node's origin, looking along its −z, up its +y; ``yfov`` (radians) and
    ``aspectRatio`` (width / height, default 1) → horizontal field of view in degrees."""
    cam = f.get("cameras", i, "a node's camera")
    if cam.get("type") != "perspective":
        out.ignored["orthographic camera"] += 1
        return None
    p = cam.get("perspective", {})
    yfov, aspect = p.get("yfov"), p.get("aspectRatio") or 1.0
    if (
        not isinstance(yfov, int | float)
        or not 0 < yfov < np.pi
        or not isinstance(aspect, int | float)
        or aspect <= 0
    ):
        f.fail(f"camera {i}: yfov must be in (0, π) and aspectRatio > 0, got {yfov!r}, {aspect!r}")
    fov = float(np.degrees(2 * np.arctan(np.tan(yfov / 2) * aspect)))
    eye = M[:3, 3]
    fwd, up = M[:3, :3] @ [0.0, 0.0, -1.0], M[:3, :3] @ [0.0, 1.0, 0.0]
    fwd, up = fwd / np.linalg.norm(fwd), up / np.linalg.norm(up)
    w = 512
    return {"eye": eye.tolist(), "target": (eye + fwd).tolist(), "up": up.tolist(), "fov": min(fov, 179.0),
            "width": w, "height": max(8, round(w / aspect)), "aspect": float(aspect)}  # fmt: skip


def _nodes(f: GltfFile, out: Loaded):
    """(node index, world matrix) of every node of the default scene, parents first; each node once."""
    scenes = f.g.get("scenes", [])
    if scenes:
        si = f.g.get("scene", 0)
        roots = f.get("scenes", si, "'scene'").get("nodes", [])
        if len(scenes) > 1:
            out.ignored["other scene"] += len(scenes) - 1
    else:  # no scene: every node that is nobody's child
        kids = {c for n in f.g.get("nodes", []) for c in n.get("children", []) if is_index(c)}
        roots = [i for i in range(len(f.g.get("nodes", []))) if i not in kids]
    if not isinstance(roots, list):
        f.fail("a scene's nodes must be an array of indices")
    seen: set[int] = set()
    stack = [(i, np.eye(4), "scene") for i in reversed(roots)]
    while stack:
        ni, parent, by = stack.pop()
        node = f.get("nodes", ni, f"{by}'s children" if by != "scene" else "the scene's nodes")
        if ni in seen:
            f.fail(f"node {ni} is reached twice (from {by}): glTF's nodes form trees, this graph has a cycle "
                   "or a node with two parents")  # fmt: skip
        seen.add(ni)
        M = parent @ _node_matrix(node)
        if not np.isfinite(M).all():
            f.fail(f"node {ni}: its transform is not finite")
        kids = node.get("children", [])
        if not isinstance(kids, list):
            f.fail(f"node {ni}: children must be an array of indices")
        stack += [(c, M, f"node {ni}") for c in reversed(kids)]
        yield ni, node, M


def _draco(f: GltfFile, prim: dict, where: str) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """(triangle indices, unique id → attribute data) of a KHR_draco_mesh_compression primitive, decoded by
    DracoPy."""
    ext = prim["extensions"]["KHR_draco_mesh_compression"]
    try:
        import DracoPy
    except ImportError:
        f.fail(f"{where} is Draco-compressed and DracoPy is not installed (pip install DracoPy)")
    buf, start, end, _ = f.view(ext.get("bufferView"), f"{where} KHR_draco_mesh_compression")
    try:
        mesh = DracoPy.decode(bytes(buf[start:end]))
    except Exception as err:  # noqa: BLE001 - the decoder's own errors are bad input
        f.fail(f"{where}: its Draco stream does not decode ({type(err).__name__}: {err})")
    attrs = {}
    for sem, uid in ext.get("attributes", {}).items():
        a = mesh.get_attribute_by_unique_id(uid) if is_index(uid) else None
        if a is None:
            f.fail(f"{where}: the Draco stream has no attribute {uid!r} (for {sem})")
        attrs[uid] = np.asarray(a["data"])
    return np.asarray(mesh.faces, np.int64).ravel(), attrs


def read_gltf(path: Path, src: str, default_color: tuple) -> Loaded:
    """The glTF at ``path`` as parts (one per material) in world space, with its punctual lights."""
    f = GltfFile(path, src)
    _check_extensions(f)
    out = Loaded([], ignored=Counter())
    mats: dict = {}
    groups: dict = {}  # material index → lists of V, F, uv, colours
    for ni, node, M in _nodes(f, out):
        if (
            "camera" in node and out.sensor is None
        ):  # the first camera of the scene: where the user looks from
            out.sensor = _camera(f, node["camera"], M, out)
        light = node.get("extensions", {}).get("KHR_lights_punctual", {}).get("light")
        if light is not None:
            _light(f, light, M, out)
        if "mesh" not in node:
            continue
        mesh = f.get("meshes", node["mesh"], f"node {ni}")
        for k, prim in enumerate(mesh.get("primitives", [])):
            where = f"mesh {node['mesh']} primitive {k}"
            mode = prim.get("mode", 4)
            if mode not in (4, 5, 6):
                out.ignored["points or lines primitive"] += 1
                continue
            attrs = prim.get("attributes", {})
            if "POSITION" not in attrs:
                f.fail(f"{where} has no POSITION attribute")
            draco = {}
            if "KHR_draco_mesh_compression" in prim.get("extensions", {}):
                idx, by_id = _draco(f, prim, where)
                draco = {
                    s: by_id[u]
                    for s, u in prim["extensions"]["KHR_draco_mesh_compression"]["attributes"].items()
                }
            P = f.accessor(attrs["POSITION"], where, draco.get("POSITION")).astype(float)
            if not draco:
                idx = (f.accessor(prim["indices"], where).ravel().astype(np.int64) if "indices" in prim
                       else np.arange(len(P)))  # fmt: skip
            F = _triangles(idx, mode)
            if len(F) and (F.min() < 0 or F.max() >= len(P)):
                f.fail(f"{where}: an index ({int(F.max())}) is past its {len(P)} vertices")
            if np.linalg.det(M[:3, :3]) < 0:
                F = F[:, ::-1]
            mat = _material(f, prim.get("material"), out, mats, default_color)
            uv_key = f"TEXCOORD_{mat['texcoord']}"
            uv = None
            if mat["texture"] is not None and uv_key in attrs:
                uv = f.accessor(attrs[uv_key], where, draco.get(uv_key)).astype(float)[:, :2]
                if mat["uv_transform"] is not None:
                    uv = uv @ mat["uv_transform"][:2, :2].T + mat["uv_transform"][:2, 2]
            col = None
            if "COLOR_0" in attrs:
                col = f.accessor(attrs["COLOR_0"], where, draco.get("COLOR_0"))[:, :3].astype(float)
            for name, a in (("uv", uv), ("COLOR_0", col)):
                if a is not None and len(a) != len(P):
                    f.fail(f"{where}: {name} has {len(a)} elements for {len(P)} positions")
            g = groups.setdefault(prim.get("material"), {"V": [], "F": [], "uv": [], "col": [], "n": 0})
            g["V"].append(P @ M[:3, :3].T + M[:3, 3])
            g["F"].append(F + g["n"])
            g["uv"].append(uv)
            g["col"].append(col)
            g["n"] += len(P)
    for mi, g in groups.items():
        mat = mats[mi]
        V, F = np.concatenate(g["V"]), np.concatenate(g["F"])
        piece = Piece(mat.get("name", "default"), V, F, emission=mat["emission"])
        if mat["texture"] is not None and all(u is not None for u in g["uv"]):
            piece.uv, piece.albedo = (
                np.concatenate(g["uv"]),
                mat["texture"],
            )  # glTF's v runs down, as Mitsuba's
        elif any(c is not None for c in g["col"]):  # COLOR_0 (linear) × baseColorFactor
            cols = [c if c is not None else np.ones((len(v), 3)) for c, v in zip(g["col"], g["V"])]
            piece.colors = np.concatenate(cols) * mat["color"]
        else:
            if mat["texture"] is not None:
                out.ignored["texture without uv"] += 1
            piece.color = tuple(mat["color"].tolist())
        out.pieces.append(piece)
    return out
