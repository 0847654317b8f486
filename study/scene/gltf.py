"""glTF 2.0 (``.gltf`` + buffers, or ``.glb``), read as the specification defines it (not through trimesh).

* Geometry: every node of the default scene (``scene``, else the first) with its mesh, placed by the node's
  ``matrix`` or translation · rotation · scale, parents first; triangle lists, strips and fans (points and lines
  are ignored, counted); accessors of any component type (normalized integers scaled as the spec says); a node
  whose transform mirrors (negative determinant) has its winding reversed.
* Materials: ``baseColorFactor`` and ``COLOR_0`` are linear; ``baseColorTexture`` is sRGB (converted, times the
  factor); ``emissiveFactor`` (linear) × ``KHR_materials_emissive_strength`` is the emitted radiance of an area
  light (an ``emissiveTexture`` contributes its mean, counted as ignored); transmission, alpha (``BLEND`` /
  ``MASK``), metal and other material extensions are not rendered (two-sided diffuse): counted as ignored.
* ``KHR_lights_punctual``: photometric → radiometric at 683 lm/W, the luminous efficacy at 555 nm that the
  Khronos exporters (Blender's among them) use both ways: point and spot ``intensity`` in candela (lm/sr) →
  W/sr = cd / 683 × ``color``; directional in lux (lm/m²) → W/m² = lx / 683 × ``color``. A spot's cone angles
  (radians, outer default π/4) become Mitsuba's ``cutoff_angle`` (outer) and ``beam_width`` (inner), in degrees.
  Lights shine along the node's −z. ``range`` is ignored (counted): Mitsuba's lights fall off as 1/r².
* ``KHR_draco_mesh_compression`` and ``EXT_meshopt_compression`` are refused in one line (no decoder here), as is
  any other required extension that is not read; sparse accessors likewise.
"""

from __future__ import annotations

import base64
import io
import json
import struct
from collections import Counter
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from study.errors import StudyError
from study.scene.parts import Loaded, Piece, image_linear

LUMENS_PER_WATT = 683.0
COMPRESSION = {
    "KHR_draco_mesh_compression": "Draco-compressed geometry",
    "EXT_meshopt_compression": "meshopt-compressed buffers",
}
READ = {"KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_mesh_quantization"}
_CT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_NC = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


class _File:
    def __init__(self, path: Path, src: str):
        self.path, self.src = path, src
        data = path.read_bytes()
        self.bin = None
        try:
            if data[:4] == b"glTF":
                n, _ = struct.unpack_from("<II", data, 12)
                self.g = json.loads(data[20 : 20 + n])
                off = 20 + n
                if off + 8 <= len(data):
                    m, kind = struct.unpack_from("<II", data, off)
                    if kind == 0x004E4942:
                        self.bin = data[off + 8 : off + 8 + m]
            else:
                self.g = json.loads(data)
        except (ValueError, struct.error) as err:
            raise StudyError(f"not a glTF 2.0 file ({err})", key=src) from None
        self._buffers: dict[int, bytes] = {}
        self.images_used: set[int] = set()

    def fail(self, msg: str):
        raise StudyError(msg, key=self.src)

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            b = self.g["buffers"][i]
            uri = b.get("uri")
            if uri is None:
                if self.bin is None:
                    self.fail(f"buffer {i} has no uri and the file has no binary chunk")
                self._buffers[i] = self.bin
            else:
                self._buffers[i] = self._uri(uri)
        return self._buffers[i]

    def _uri(self, uri: str) -> bytes:
        if uri.startswith("data:"):
            return base64.b64decode(uri.split(",", 1)[1])
        p = self.path.parent / unquote(uri)
        if not p.is_file():
            self.fail(f"the file it references is missing: {p}")
        return p.read_bytes()

    def view(self, i: int) -> tuple[bytes, int, int | None]:
        v = self.g["bufferViews"][i]
        return self.buffer(v["buffer"]), v.get("byteOffset", 0), v.get("byteStride")

    def accessor(self, i: int) -> np.ndarray:
        a = self.g["accessors"][i]
        if "sparse" in a:
            self.fail(
                f"accessor {i} is sparse, which study does not read; re-export without sparse accessors"
            )
        dt, nc, count = np.dtype(_CT[a["componentType"]]).newbyteorder("<"), _NC[a["type"]], a["count"]
        if "bufferView" not in a:
            out = np.zeros((count, nc), dt)
        else:
            buf, off, stride = self.view(a["bufferView"])
            off += a.get("byteOffset", 0)
            size = dt.itemsize * nc
            stride = stride or size
            raw = np.frombuffer(buf, np.uint8, count=(count - 1) * stride + size if count else 0, offset=off)
            rows = (
                np.lib.stride_tricks.as_strided(raw, (count, size), (stride, 1))
                if count
                else raw.reshape(0, size)
            )
            out = np.ascontiguousarray(rows).view(dt).reshape(count, nc)
        if a.get("normalized") and dt.kind in "iu":
            out = np.maximum(out / np.iinfo(dt).max, -1.0)
        return out

    def image(self, i: int):
        from PIL import Image

        im = self.g["images"][i]
        if "uri" in im:
            data = self._uri(im["uri"])
        else:
            buf, off, _ = self.view(im["bufferView"])
            v = self.g["bufferViews"][im["bufferView"]]
            data = buf[off : off + v["byteLength"]]
        try:
            return Image.open(io.BytesIO(data))
        except OSError as err:
            self.fail(f"image {i} cannot be read ({err})")


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
    k = np.arange(len(idx) - 2)
    if mode == 5:  # strip: every other triangle reversed to keep the winding
        t = np.stack([idx[k], idx[k + 1], idx[k + 2]], 1)
        t[1::2] = t[1::2][:, [1, 0, 2]]
        return t
    return np.stack([np.full(len(k), idx[0]), idx[k + 1], idx[k + 2]], 1)  # fan


def _check_extensions(f: _File) -> None:
    used = set(f.g.get("extensionsUsed", [])) | set(f.g.get("extensionsRequired", []))
    for ext, what in COMPRESSION.items():
        if ext in used:
            f.fail(f"uses {ext} ({what}), which study cannot decode; re-export it uncompressed")
    other = sorted(set(f.g.get("extensionsRequired", [])) - READ - {"KHR_texture_transform"})
    if other:
        f.fail(f"requires {', '.join(other)}, which study does not read")
    if str(f.g.get("asset", {}).get("version", "2.0")).split(".")[0] != "2":
        f.fail(f"glTF version {f.g['asset']['version']}; study reads glTF 2.0")


def _material(f: _File, i: int | None, out: Loaded, cache: dict, default: tuple) -> dict:
    """{"color", "texture", "texcoord", "emission"} of material ``i`` (counted once in ``out``)."""
    if i in cache:
        return cache[i]
    if i is None:
        cache[i] = {"color": np.asarray(default, float), "texture": None, "texcoord": 0, "emission": None}
        return cache[i]
    m = f.g["materials"][i]
    pbr = m.get("pbrMetallicRoughness", {})
    ext = m.get("extensions", {})
    color = np.asarray(pbr.get("baseColorFactor", (1, 1, 1, 1))[:3], float)  # linear, as the spec says
    tex, texcoord = None, 0
    if "baseColorTexture" in pbr:
        t = f.g["textures"][pbr["baseColorTexture"]["index"]]
        if "source" in t:
            tex = image_linear(f.image(t["source"])) * color.astype(np.float32)  # sRGB image × linear factor
            texcoord = pbr["baseColorTexture"].get("texCoord", 0)
            f.images_used.add(t["source"])
            out.textures = len(f.images_used)
            if "KHR_texture_transform" in pbr["baseColorTexture"].get("extensions", {}):
                out.ignored["texture transform"] += 1
    emission = np.asarray(m.get("emissiveFactor", (0, 0, 0)), float)
    emission = emission * ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
    if "emissiveTexture" in m and emission.max() > 0:
        t = f.g["textures"][m["emissiveTexture"]["index"]]
        if "source" in t:
            emission = emission * image_linear(f.image(t["source"])).reshape(-1, 3).mean(0)
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
        "emission": tuple(emission.tolist()) if emission.max() > 0 else None,
        "name": m.get("name") or f"material{i}",
    }
    return cache[i]


def _light(f: _File, i: int, M: np.ndarray, out: Loaded) -> None:
    li = f.g.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])[i]
    rgb = np.asarray(li.get("color", (1, 1, 1)), float) * li.get("intensity", 1.0) / LUMENS_PER_WATT
    pos, d = M[:3, 3], M[:3, :3] @ np.array([0.0, 0.0, -1.0])
    d = d / (np.linalg.norm(d) or 1)
    if "range" in li:
        out.ignored["light range"] += 1
    kind = li.get("type")
    if kind == "point":
        out.lights.append({"type": "point", "position": pos.tolist(), "intensity": rgb.tolist()})
    elif kind == "spot":
        s = li.get("spot", {})
        out.lights.append(
            {
                "type": "spot",
                "position": pos.tolist(),
                "direction": d.tolist(),
                "intensity": rgb.tolist(),
                "cutoff_angle": float(np.degrees(s.get("outerConeAngle", np.pi / 4))),
                "beam_width": float(np.degrees(s.get("innerConeAngle", 0.0))),
            }
        )
    elif kind == "directional":
        out.lights.append({"type": "directional", "direction": d.tolist(), "irradiance": rgb.tolist()})
    else:
        out.ignored[f"light of type {kind!r}"] += 1


def _camera(f: _File, i: int, M: np.ndarray, out: Loaded) -> dict | None:
    """A perspective camera: at the node's origin, looking along its −z, up its +y; ``yfov`` (radians) and
    ``aspectRatio`` (width / height, default 1) → horizontal field of view in degrees."""
    cam = f.g["cameras"][i]
    if cam.get("type") != "perspective":
        out.ignored["orthographic camera"] += 1
        return None
    p = cam.get("perspective", {})
    aspect = p.get("aspectRatio") or 1.0
    fov = float(np.degrees(2 * np.arctan(np.tan(p["yfov"] / 2) * aspect)))
    eye = M[:3, 3]
    fwd, up = M[:3, :3] @ [0.0, 0.0, -1.0], M[:3, :3] @ [0.0, 1.0, 0.0]
    fwd, up = fwd / np.linalg.norm(fwd), up / np.linalg.norm(up)
    w = 512
    return {"eye": eye.tolist(), "target": (eye + fwd).tolist(), "up": up.tolist(), "fov": min(fov, 179.0),
            "width": w, "height": max(8, round(w / aspect))}  # fmt: skip


def read_gltf(path: Path, src: str, default_color: tuple) -> Loaded:
    """The glTF at ``path`` as parts (one per material) in world space, with its punctual lights."""
    f = _File(path, src)
    _check_extensions(f)
    out = Loaded([], ignored=Counter())
    mats: dict = {}
    groups: dict = {}  # material index → lists of V, F, uv, colours
    scenes = f.g.get("scenes", [])
    if scenes:
        roots = scenes[f.g.get("scene", 0)].get("nodes", [])
    else:  # no scene: every node that is nobody's child
        kids = {c for n in f.g.get("nodes", []) for c in n.get("children", [])}
        roots = [i for i in range(len(f.g.get("nodes", []))) if i not in kids]
    stack = [(i, np.eye(4)) for i in roots]
    while stack:
        ni, parent = stack.pop()
        node = f.g["nodes"][ni]
        M = parent @ _node_matrix(node)
        stack += [(c, M) for c in node.get("children", [])]
        if (
            "camera" in node and out.sensor is None
        ):  # the first camera of the scene: where the user looks from
            out.sensor = _camera(f, node["camera"], M, out)
        light = node.get("extensions", {}).get("KHR_lights_punctual", {}).get("light")
        if light is not None:
            _light(f, light, M, out)
        if "mesh" not in node:
            continue
        for prim in f.g["meshes"][node["mesh"]]["primitives"]:
            mode = prim.get("mode", 4)
            if mode not in (4, 5, 6):
                out.ignored["points or lines primitive"] += 1
                continue
            attrs = prim["attributes"]
            P = f.accessor(attrs["POSITION"]).astype(float)
            idx = (
                f.accessor(prim["indices"]).ravel().astype(np.int64)
                if "indices" in prim
                else np.arange(len(P))
            )
            F = _triangles(idx, mode)
            if np.linalg.det(M[:3, :3]) < 0:
                F = F[:, ::-1]
            mat = _material(f, prim.get("material"), out, mats, default_color)
            uv_key = f"TEXCOORD_{mat['texcoord']}"
            uv = (
                f.accessor(attrs[uv_key]).astype(float)
                if mat["texture"] is not None and uv_key in attrs
                else None
            )
            col = f.accessor(attrs["COLOR_0"])[:, :3].astype(float) if "COLOR_0" in attrs else None
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
