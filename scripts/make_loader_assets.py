"""Write the small scene files the loader tests read (tests/assets/), by hand from the formats' specifications
(not through trimesh): a 4 m × 3 m × 4 m room, (-2, 0, -2)..(2, 3, 2), in each format.

* ``neg_room.obj`` + ``neg_room.mtl``: faces with negative (relative) indices, MTL ``Kd`` 0.63 walls, a ``Ke``
  lamp, an ``l`` element and an alpha (``d``) material;
* ``room.gltf`` + ``room.bin`` + ``wall.png``: an external buffer and texture, ``baseColorFactor`` 0.137 floor,
  an emissive lamp (``KHR_materials_emissive_strength``), a ``KHR_lights_punctual`` point light and a window
  with transmission and alpha;
* ``draco.glb``: a GLB that requires ``KHR_draco_mesh_compression``;
* ``xml/main.xml``: ``<include>`` of ``xml/walls.xml``, an OBJ mesh (``xml/block.obj``), a bitmap texture, an
  envmap (``xml/sky.exr``) and an area light.

    .venv/bin/python scripts/make_loader_assets.py        # writes tests/assets/
"""

from __future__ import annotations

import json
import struct
import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "tests" / "assets"
LO, HI = np.array([-2.0, 0.0, -2.0]), np.array([2.0, 3.0, 2.0])


def quad(p0, du, dv):
    """Four corners p0, p0+du, p0+du+dv, p0+dv (counter-clockwise seen from du × dv)."""
    p0, du, dv = map(np.asarray, (p0, du, dv))
    return np.array([p0, p0 + du, p0 + du + dv, p0 + dv], float)


def room_quads() -> dict[str, np.ndarray]:
    """The room's six faces, normals pointing in, and a lamp under the ceiling facing down."""
    s = HI - LO
    ex, ey, ez = np.diag(s)
    return {
        "floor": quad(LO, ez, ex),
        "ceiling": quad(LO + ey, ex, ez),
        "wall_x-": quad(LO, ey, ez),
        "wall_x+": quad(LO + ex, ez, ey),
        "wall_z-": quad(LO, ex, ey),
        "wall_z+": quad(LO + ez, ey, ex),
        "lamp": quad([-0.3, 2.95, -0.3], [0.6, 0, 0], [0, 0, 0.6]),
    }


def write_obj() -> None:
    q = room_quads()
    mats = {"floor": "floor", "ceiling": "walls", "lamp": "lamp"}
    lines = [
        "# made by scripts/make_loader_assets.py: negative (relative) face indices",
        "mtllib neg_room.mtl",
    ]
    for name, c in q.items():
        lines += [f"o {name}", f"usemtl {mats.get(name, 'walls')}"]
        lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in c]
        lines += ["vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1"] if name == "floor" else []
        lines.append("f -4/-4 -3/-3 -2/-2 -1/-1" if name == "floor" else "f -4 -3 -2 -1")
    lines += ["o wire", "l -1 -2"]
    (OUT / "neg_room.obj").write_text("\n".join(lines) + "\n")
    (OUT / "neg_room.mtl").write_text(
        "newmtl walls\nKd 0.63 0.63 0.63\n\nnewmtl floor\nKd 1 1 1\nmap_Kd wall.png\nd 0.5\n\n"
        "newmtl lamp\nKd 0.8 0.8 0.8\nKe 12 11 10\n"
    )


def write_png() -> None:
    from PIL import Image

    y, x = np.mgrid[0:16, 0:16]
    img = np.where(((x // 4 + y // 4) % 2)[..., None], [200, 180, 150], [60, 50, 40]).astype(np.uint8)
    Image.fromarray(img).save(OUT / "wall.png")


def write_gltf() -> None:
    q = room_quads()
    window = quad([-0.5, 1.0, 1.99], [0, 1.0, 0], [1.0, 0, 0])  # on wall_z+, facing in
    prims = {"floor": 0, "ceiling": 1, "wall_x-": 1, "wall_x+": 1, "wall_z-": 1, "wall_z+": 1, "lamp": 2}
    blob, views, accessors, meshes = b"", [], [], []

    def add(arr: np.ndarray, target: int | None, ctype: int, kind: str) -> int:
        nonlocal blob
        data = arr.tobytes()
        views.append(
            {"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)}
            | ({"target": target} if target else {})
        )
        blob += data + b"\0" * (-len(data) % 4)
        acc = {"bufferView": len(views) - 1, "componentType": ctype, "count": len(arr), "type": kind}
        if kind == "VEC3":
            acc |= {"min": arr.min(0).tolist(), "max": arr.max(0).tolist()}
        accessors.append(acc)
        return len(accessors) - 1

    idx = add(np.array([0, 1, 2, 0, 2, 3], np.uint16), 34963, 5123, "SCALAR")
    uv = add(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32), 34962, 5126, "VEC2")
    for name, c in [*q.items(), ("window", window)]:
        pos = add(c.astype(np.float32), 34962, 5126, "VEC3")
        attrs = {"POSITION": pos, "TEXCOORD_0": uv}
        meshes.append(
            {
                "name": name,
                "primitives": [{"attributes": attrs, "indices": idx, "material": prims.get(name, 3)}],
            }
        )
    nodes = [{"mesh": i, "name": m["name"]} for i, m in enumerate(meshes)]
    nodes.append(
        {"name": "bulb", "translation": [1.0, 2.5, 1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}
    )
    g = {
        "asset": {"version": "2.0", "generator": "scripts/make_loader_assets.py (by hand)"},
        "extensionsUsed": [
            "KHR_lights_punctual",
            "KHR_materials_emissive_strength",
            "KHR_materials_transmission",
        ],
        "extensions": {
            "KHR_lights_punctual": {"lights": [{"type": "point", "color": [1, 1, 1], "intensity": 2049.0}]}
        },
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [
            {
                "name": "floor",
                "pbrMetallicRoughness": {"baseColorFactor": [0.137, 0.137, 0.137, 1.0], "metallicFactor": 0},
            },
            {
                "name": "walls",
                "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0},
            },
            {
                "name": "lamp",
                "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0},
                "emissiveFactor": [1.0, 0.9, 0.8],
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 5.0}},
            },
            {
                "name": "window",
                "alphaMode": "BLEND",
                "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 1.0, 0.3], "metallicFactor": 0},
                "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}},
            },
        ],
        "textures": [{"source": 0}],
        "images": [{"uri": "wall.png"}],
        "buffers": [{"uri": "room.bin", "byteLength": len(blob)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    (OUT / "room.bin").write_bytes(blob)
    (OUT / "room.gltf").write_text(json.dumps(g, indent=1) + "\n")


def write_draco() -> None:
    g = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {"POSITION": 0},
                        "extensions": {
                            "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}
                        },
                    }
                ]
            }
        ],
        "accessors": [
            {"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}
        ],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 4}],
        "buffers": [{"byteLength": 4}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
    }
    js = json.dumps(g).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", 4, 0x004E4942) + b"\0" * 4
    (OUT / "draco.glb").write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)


WALLS = """<scene version="3.0.0">
  <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.6, 0.6, 0.6"/></bsdf>
  <bsdf type="diffuse" id="tiles"><texture type="bitmap" name="reflectance">
    <string name="filename" value="tex/wall.png"/></texture></bsdf>
  <shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/><translate y="-1"/>
    </transform><ref id="tiles"/></shape>
  <shape type="rectangle" id="back"><transform name="to_world"><translate z="-1"/></transform><ref id="grey"/></shape>
  <shape type="rectangle" id="ceiling"><transform name="to_world"><rotate x="1" angle="90"/><translate y="1"/>
    </transform><ref id="grey"/></shape>
  <shape type="rectangle" id="left"><transform name="to_world"><rotate y="1" angle="90"/><translate x="-1"/>
    </transform><ref id="grey"/></shape>
  <shape type="rectangle" id="right"><transform name="to_world"><rotate y="1" angle="-90"/><translate x="1"/>
    </transform><ref id="grey"/></shape>
</scene>
"""
MAIN = """<scene version="3.0.0">
  <include filename="walls.xml"/>
  <shape type="obj" id="block"><string name="filename" value="block.obj"/>
    <transform name="to_world"><scale value="0.25"/><translate x="-0.5" y="-0.75"/></transform>
    <bsdf type="diffuse"/></shape>
  <shape type="rectangle" id="lamp"><transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/>
    <translate y="0.98"/></transform><emitter type="area"><rgb name="radiance" value="10, 10, 10"/></emitter>
    <bsdf type="diffuse"/></shape>
  <emitter type="envmap"><string name="filename" value="sky.exr"/><float name="scale" value="0.5"/></emitter>
</scene>
"""


def write_xml() -> None:
    d = OUT / "xml"
    d.mkdir(exist_ok=True)
    (d / "walls.xml").write_text(WALLS)
    (d / "main.xml").write_text(MAIN)
    (d / "tex").mkdir(exist_ok=True)  # files a scene names lie in its folder (study.scene.paths)
    (d / "tex" / "wall.png").write_bytes((OUT / "wall.png").read_bytes())
    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = [(1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6)]
    (d / "block.obj").write_text(
        "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in c)
        + "".join(f"f {a} {b} {e} {f_}\n" for a, b, e, f_ in faces)
    )
    sys.path.insert(0, str(OUT.parents[1]))
    from study import runtime

    m = runtime.mitsuba()
    sky = np.ones((8, 16, 3), np.float32) * np.array([0.4, 0.6, 1.0], np.float32)
    m.Bitmap(sky).write(str(d / "sky.exr"))


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    write_png()
    write_obj()
    write_gltf()
    write_draco()
    write_xml()
    print(f"wrote {OUT}")
