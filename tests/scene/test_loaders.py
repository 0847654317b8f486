"""Mesh files read as their formats define them (issue 26): every referenced file in the content key, OBJ and glTF
read right or refused in one line, colours and lights as the specifications say, one summary line per load.

The assets (tests/assets/, written by scripts/make_loader_assets.py by hand from the specifications, not through
trimesh) are a 4 m × 3 m × 4 m room, (-2, 0, -2)..(2, 3, 2), in each format.
"""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from study.errors import StudyError
from study.scene import scene_from_dict
from study.scene.environment import geometry
from study.scene.parts import srgb_to_linear
from study.scene.sources import key_fields

ROOT = Path(__file__).resolve().parents[2]
ASSETS = ROOT / "tests" / "assets"


@pytest.fixture
def assets(tmp_path) -> Path:
    shutil.copytree(ASSETS, tmp_path / "a")
    return tmp_path / "a"


def mesh_env(path, **over) -> dict:
    return {"type": "mesh", "file": str(path), **over}


def key(path: Path) -> dict:
    kind = "mitsuba" if path.suffix == ".xml" else "mesh"
    return key_fields({"environment": {"type": kind, "file": str(path)}})


# ---------------------------------------------------------------------------------------------- content keys
@pytest.mark.parametrize(
    "main, referenced",
    [
        ("room.gltf", "room.bin"),  # a glTF buffer
        ("room.gltf", "wall.png"),  # a glTF image
        ("neg_room.obj", "neg_room.mtl"),  # an OBJ material library
        ("neg_room.obj", "wall.png"),  # an MTL texture (map_Kd)
        ("xml/main.xml", "xml/walls.xml"),  # a Mitsuba <include>
        ("xml/main.xml", "xml/block.obj"),  # a Mitsuba mesh filename
        ("xml/main.xml", "xml/tex/wall.png"),  # a Mitsuba bitmap texture (in the included file, tex/wall.png)
        ("xml/main.xml", "xml/sky.exr"),  # a Mitsuba envmap
    ],
)
def test_every_referenced_file_is_in_the_content_key(assets, main, referenced):
    before = key(assets / main)
    assert before == key(assets / main)
    f = assets / referenced
    f.write_bytes(f.read_bytes() + b"\n")  # other bytes, same name
    assert key(assets / main) != before


def test_a_changed_texture_is_loaded_again_not_taken_from_the_memo(assets):
    from PIL import Image

    a = geometry(mesh_env(assets / "room.gltf"))
    img = np.asarray(Image.open(assets / "wall.png"))
    Image.fromarray(255 - img).save(assets / "wall.png")  # inverted
    b = geometry(mesh_env(assets / "room.gltf"))
    ta = next(p.albedo for p in a.parts if p.albedo is not None)
    tb = next(p.albedo for p in b.parts if p.albedo is not None)
    assert not np.allclose(ta, tb)


# ---------------------------------------------------------------------------------------------- OBJ
def test_obj_negative_indices_are_relative_to_the_vertices_so_far():
    env = geometry(mesh_env(ASSETS / "neg_room.obj"))
    np.testing.assert_allclose(env.bounds[0], [-2, 0, -2])
    np.testing.assert_allclose(env.bounds[1], [2, 3, 2])
    assert len(env.mesh.faces) == 14  # six walls and the lamp, two triangles each
    V = env.mesh.vertices[env.mesh.faces]
    lamp = V[env.mesh.surface == env.mesh.surfaces.index("part2:lamp")]
    np.testing.assert_allclose(lamp[..., 1], 2.95)  # the lamp's own four vertices, not the first three
    n = np.cross(V[:, 1] - V[:, 0], V[:, 2] - V[:, 0])
    centre = np.array([0.0, 1.5, 0.0])
    assert (np.einsum("ij,ij->i", n, centre - V[:, 0]) > 0).all()  # every face faces the room's inside


@pytest.mark.parametrize(
    "text, words",
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "index 0"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "index -4 refers past the end of the list (3 defined"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\nv 1 1 1\n", "index 4 refers past"),
        ("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", "not finite"),
        ("v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n", "not finite"),
    ],
)
def test_bad_obj_is_refused_in_one_line(tmp_path, text, words):
    (tmp_path / "bad.obj").write_text(text)
    with pytest.raises(StudyError) as e:
        geometry(mesh_env(tmp_path / "bad.obj"))
    msg = str(e.value)
    assert msg.startswith("environment.file:") and words in msg, msg
    assert "\n" not in msg


def test_degenerate_and_empty_parts_are_dropped_with_a_count(tmp_path):
    (tmp_path / "d.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nusemtl a\nf 1 2 3\nf 1 2 4\nf 1 1 3\nusemtl b\nf 1 2 4\n"
    )
    env = geometry(mesh_env(tmp_path / "d.obj"))
    assert len(env.mesh.faces) == 1
    assert "dropped: 3 degenerate triangles, 1 empty part" in env.summary, env.summary


# ---------------------------------------------------------------------------------------------- glTF
def test_a_draco_stream_that_does_not_decode_is_refused_in_one_line_at_once():
    import time

    t = time.perf_counter()
    with pytest.raises(StudyError) as e:
        scene_from_dict({"environment": mesh_env(ASSETS / "draco.glb")}, source="s.toml")
    msg = str(e.value)
    assert msg.startswith("s.toml: environment.file:") and "Draco stream does not decode" in msg, msg
    assert "\n" not in msg
    assert time.perf_counter() - t < 5


def test_unknown_required_extensions_are_refused(tmp_path):
    import json

    g = json.loads((ASSETS / "room.gltf").read_text())
    for ext in ("KHR_made_up",):
        g2 = {**g, "extensionsRequired": [ext], "extensionsUsed": [*g["extensionsUsed"], ext]}
        shutil.copy(ASSETS / "room.bin", tmp_path / "room.bin")
        shutil.copy(ASSETS / "wall.png", tmp_path / "wall.png")
        (tmp_path / "x.gltf").write_text(json.dumps(g2))
        with pytest.raises(StudyError, match=ext):
            geometry(mesh_env(tmp_path / "x.gltf"))


# ---------------------------------------------------------------------------------------------- colours, lights
def test_colours_are_linear_as_the_specifications_say():
    from PIL import Image

    gl = {p.name.split(":")[-1]: p for p in geometry(mesh_env(ASSETS / "room.gltf")).parts}
    assert gl["floor"].color == pytest.approx((0.137, 0.137, 0.137))  # baseColorFactor: linear, kept
    png = np.asarray(Image.open(ASSETS / "wall.png").convert("RGB"), float) / 255
    np.testing.assert_allclose(gl["walls"].albedo, srgb_to_linear(png), rtol=1e-6)  # baseColorTexture: sRGB
    ob = {p.name.split(":")[-1]: p for p in geometry(mesh_env(ASSETS / "neg_room.obj")).parts}
    assert ob["walls"].color == pytest.approx((0.63, 0.63, 0.63))  # MTL Kd: linear, kept
    np.testing.assert_allclose(ob["floor"].albedo, srgb_to_linear(png), rtol=1e-6)  # map_Kd (× Kd 1): sRGB


def test_emission_and_punctual_lights():
    gl = geometry(mesh_env(ASSETS / "room.gltf"))
    lamp = next(p for p in gl.parts if p.name.endswith("lamp"))
    assert lamp.emission == pytest.approx((5.0, 4.5, 4.0))  # emissiveFactor × emissiveStrength
    (light,) = gl.lights
    assert light["type"] == "point" and light["position"] == pytest.approx([1.0, 2.5, 1.0])
    assert light["intensity"] == pytest.approx([3.0, 3.0, 3.0])  # 2049 cd / 683 lm/W
    moved = geometry(mesh_env(ASSETS / "room.gltf", scale=2.0, translate=(1.0, 0.0, 0.0)))
    assert moved.lights[0]["position"] == pytest.approx([3.0, 5.0, 2.0])
    ob = geometry(mesh_env(ASSETS / "neg_room.obj"))
    assert next(p for p in ob.parts if p.name.endswith("lamp")).emission == (12.0, 11.0, 10.0)  # Ke


def test_emissive_parts_render_as_area_lights():
    """A ray from the room's centre straight up meets the lamp: Mitsuba returns its emitted radiance."""
    from study.reference.mitsuba import radiance_along

    for f, want in (("room.gltf", (5.0, 4.5, 4.0)), ("neg_room.obj", (12.0, 11.0, 10.0))):
        scene = scene_from_dict({"environment": mesh_env(ASSETS / f), "render": {"max_depth": 2}})
        assert not scene.lamp()  # the file brings its own light: no point light added
        o, d = np.array([[0.0, 1.5, 0.0]]), np.array([[0.0, 1.0, 0.0]])
        rgb = radiance_along(scene, o, d, spp=4, max_depth=1)  # emission only
        np.testing.assert_allclose(rgb[0], want, rtol=1e-4)


def test_spot_and_directional_lights_convert(tmp_path):
    import json

    g = json.loads((ASSETS / "room.gltf").read_text())
    g["extensions"]["KHR_lights_punctual"]["lights"] = [
        {"type": "spot", "intensity": 683.0, "color": [1, 0.5, 0.25], "spot": {"outerConeAngle": 0.5}},
        {"type": "directional", "intensity": 1366.0},
    ]
    g["nodes"].append({"translation": [0, 1, 0], "extensions": {"KHR_lights_punctual": {"light": 1}}})
    g["scenes"][0]["nodes"].append(len(g["nodes"]) - 1)
    shutil.copy(ASSETS / "room.bin", tmp_path / "room.bin")
    shutil.copy(ASSETS / "wall.png", tmp_path / "wall.png")
    (tmp_path / "s.gltf").write_text(json.dumps(g))
    lights = {li["type"]: li for li in geometry(mesh_env(tmp_path / "s.gltf")).lights}
    spot, sun = lights["spot"], lights["directional"]
    assert spot["intensity"] == pytest.approx([1.0, 0.5, 0.25]) and spot["direction"] == pytest.approx(
        [0, 0, -1]
    )
    assert spot["cutoff_angle"] == pytest.approx(np.degrees(0.5)) and spot["beam_width"] == 0.0
    assert sun["irradiance"] == pytest.approx([2.0, 2.0, 2.0])
    from study.reference.mitsuba import mi, punctual

    m = mi()
    for li in lights.values():
        m.load_dict(punctual(m, li))  # Mitsuba takes them


def test_an_unlit_file_gets_a_light_scaled_to_its_size(tmp_path):
    (tmp_path / "r.obj").write_text((ASSETS / "neg_room.obj").read_text().replace("mtllib neg_room.mtl", ""))
    small = scene_from_dict({"environment": mesh_env(tmp_path / "r.obj")})
    big = scene_from_dict({"environment": mesh_env(tmp_path / "r.obj", scale=5.0)})
    assert small.lamp() and big.lamp()
    assert small.light.intensity[0] == pytest.approx(6.0 * (np.sqrt(41) / np.sqrt(41)) ** 2, rel=1e-6)
    assert big.light.intensity[0] == pytest.approx(25 * small.light.intensity[0])
    lo, hi = big.bounds()
    c, ref = (lo + hi) / 2, np.asarray(big.reference.point)
    above = ref + [0, 0.6 * big.object.radius / 0.25, 0]  # the centre is the reference point here: above it
    assert np.allclose(big.light.position, c) or np.allclose(big.light.position, above, rtol=1e-3)


# ---------------------------------------------------------------------------------------------- summaries
SUMMARIES = {
    "neg_room.obj": "loaded neg_room.obj: 14 triangles, 3 materials, 1 texture, 1 emissive material, "
    "0 punctual lights; ignored: 1 alpha, 1 line",
    "room.gltf": "loaded room.gltf: 16 triangles, 4 materials, 1 texture, 1 emissive material, "
    "1 punctual light; ignored: 1 alpha, 1 transmission",
    "xml/main.xml": "loaded main.xml: 24 triangles, 4 shapes, 1 area light(s), 1 other emitter(s)",
}


@pytest.mark.parametrize("name", SUMMARIES)
def test_one_summary_line_per_load(name):
    kind = "mitsuba" if name.endswith(".xml") else "mesh"
    assert geometry({"type": kind, "file": str(ASSETS / name)}).summary == SUMMARIES[name]


def test_the_cli_prints_the_summary_to_stderr(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "study.cli", "run", str(ASSETS / "room.gltf"), "-m", "classical", "--out",
         str(tmp_path / "o"), "--cache", str(tmp_path / "c"), "--set", "render.cube_res=8", "--set",
         "render.cube_spp=1", "--set", "render.spp=1", "--set", "camera.width=16", "--set", "camera.height=16",
         "--set", "render.supersample=1"],
        capture_output=True, text=True, cwd=tmp_path, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    assert SUMMARIES["room.gltf"] in out.stderr


# ---------------------------------------------------------------------------------------------- by hand, in tmp_path
def write_glb(path: Path, V: np.ndarray, F: np.ndarray, node: dict | None = None, mode: int = 4) -> Path:
    """A GLB of one mesh (V, F) written from the glTF 2.0 specification (tests/scene/test_real_files.py's writer), with
    the node's transform and the primitive's mode."""
    from tests.scene.test_real_files import gltf_doc
    from tests.scene.test_real_files import write_glb as glb

    g, blob = gltf_doc(V, F)
    g["nodes"][0].update(node or {})
    g["meshes"][0]["primitives"][0]["mode"] = mode
    return glb(path, g, blob)


def test_glb_node_transforms_and_strips(tmp_path):
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    node = {
        "translation": [1, 2, 3],
        "rotation": [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)],
        "scale": [2, 2, 2],
    }
    env = geometry(mesh_env(write_glb(tmp_path / "t.glb", V, np.array([[0, 1, 2], [2, 1, 3]]), node)))
    # scale 2, then 90° about z ((x, y) → (−y, x)), then moved by (1, 2, 3)
    want = np.c_[-2 * V[:, 1], 2 * V[:, 0], 2 * V[:, 2]] + [1, 2, 3]
    np.testing.assert_allclose(np.sort(env.mesh.vertices, 0), np.sort(want, 0), atol=1e-6)
    strip = geometry(mesh_env(write_glb(tmp_path / "s.glb", V, np.array([0, 1, 2, 3]), mode=5)))
    n = np.cross(*(strip.mesh.vertices[strip.mesh.faces][:, k] - strip.mesh.vertices[strip.mesh.faces][:, 0]
                   for k in (1, 2)))  # fmt: skip
    assert len(strip.mesh.faces) == 2 and (n[:, 2] > 0).all()  # a strip keeps one winding


def test_a_glb_cornell_box_is_read_whole():
    mesh = geometry({"type": "mitsuba", "builtin": "cornell_box"}).mesh
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        env = geometry(mesh_env(write_glb(Path(d) / "cornell.glb", mesh.vertices, mesh.faces)))
    np.testing.assert_allclose(env.mesh.vertices[env.mesh.faces], mesh.vertices[mesh.faces], atol=1e-6)
    assert env.summary.startswith(f"loaded cornell.glb: {len(mesh.faces)} triangles")


def test_non_finite_ply_vertices_are_refused(tmp_path):
    (tmp_path / "n.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n"
    )
    with pytest.raises(StudyError, match="vertex 1 is not finite"):
        geometry(mesh_env(tmp_path / "n.ply"))


def test_a_mitsuba_scene_without_emitters_gets_the_scaled_light():
    env = {"type": "mitsuba", "scene": {"type": "scene", "room": {"type": "cube", "flip_normals": True}}}
    scene = scene_from_dict({"environment": env})
    assert scene.lamp() and geometry(env).summary.endswith("no emitter: the point light [light] lights it")
    assert scene.light.intensity[0] == pytest.approx(6.0 * 12 / 41)  # (diagonal √12 / default √41)²


def test_an_xml_filename_given_by_a_default_parameter_is_in_the_key(assets):
    main = assets / "xml" / "main.xml"
    main.write_text(
        main.read_text()
        .replace(
            '<scene version="3.0.0">', '<scene version="3.0.0">\n  <default name="sky" value="sky.exr"/>', 1
        )
        .replace('value="sky.exr"/><float', 'value="$sky"/><float')
    )
    before = key(main)
    (assets / "xml" / "sky.exr").write_bytes((assets / "xml" / "sky.exr").read_bytes() + b"\n")
    assert key(main) != before


def test_an_object_obj_with_negative_indices_is_the_same_object(tmp_path):
    from study.scene.objects import object_mesh

    tet = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
    (tmp_path / "pos.obj").write_text(tet + "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    (tmp_path / "neg.obj").write_text(tet + "f -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n")
    a, b = (object_mesh(scene_from_dict({"object": {"file": str(tmp_path / n), "radius": 0.3}}).object)
            for n in ("pos.obj", "neg.obj"))  # fmt: skip
    np.testing.assert_allclose(a.vertices, b.vertices)
    assert np.array_equal(a.faces, b.faces) and len(a.faces) == 4


def test_a_gltf_camera_is_the_view_and_the_object_stands_before_the_first_occluder(tmp_path):
    """The glTF's camera (node at z = 1.9 looking along −z, yfov 60°, aspect 1.5) is the suggested camera; a
    panel (from a data: URI buffer) blocks its view axis at z = 0.5, so the object stands between the two."""
    import base64
    import json

    from study.reference.embree import Tracer
    from study.scene import placement

    g = json.loads((ASSETS / "room.gltf").read_text())
    panel = np.array([[-1, 0.5, 0.5], [1, 0.5, 0.5], [1, 2.5, 0.5], [-1, 2.5, 0.5]], np.float32)  # faces +z
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    data = panel.tobytes() + idx.tobytes()
    g["buffers"].append({"uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
                         "byteLength": len(data)})  # fmt: skip
    b = len(g["buffers"]) - 1
    g["bufferViews"] += [{"buffer": b, "byteOffset": 0, "byteLength": 48},
                         {"buffer": b, "byteOffset": 48, "byteLength": 12}]  # fmt: skip
    nv = len(g["bufferViews"])
    g["accessors"] += [{"bufferView": nv - 2, "componentType": 5126, "count": 4, "type": "VEC3"},
                       {"bufferView": nv - 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]  # fmt: skip
    na = len(g["accessors"])
    g["meshes"].append(
        {"primitives": [{"attributes": {"POSITION": na - 2}, "indices": na - 1, "material": 0}]}
    )
    g["nodes"] += [{"mesh": len(g["meshes"]) - 1},
                   {"camera": 0, "translation": [0.0, 1.5, 1.9]}]  # fmt: skip
    g["scenes"][0]["nodes"] += [len(g["nodes"]) - 2, len(g["nodes"]) - 1]
    g["cameras"] = [{"type": "perspective", "perspective": {"yfov": np.radians(60), "aspectRatio": 1.5,
                                                             "znear": 0.01}}]  # fmt: skip
    for n in ("room.bin", "wall.png"):
        shutil.copy(ASSETS / n, tmp_path / n)
    (tmp_path / "cam.gltf").write_text(json.dumps(g))
    env = geometry(mesh_env(tmp_path / "cam.gltf"))
    s = env.sensor
    assert s["eye"] == pytest.approx([0, 1.5, 1.9]) and s["target"] == pytest.approx([0, 1.5, 0.9])
    assert s["fov"] == pytest.approx(np.degrees(2 * np.arctan(np.tan(np.radians(30)) * 1.5)))
    scene = scene_from_dict({"environment": mesh_env(tmp_path / "cam.gltf")})
    assert scene.camera.eye == pytest.approx((0, 1.5, 1.9)) and scene.camera.fov == pytest.approx(s["fov"])
    eye, c, r = np.asarray(scene.camera.eye), np.asarray(scene.object.center), scene.object.radius
    assert 0.5 + r < c[2] < 1.9 - r  # before the panel, not behind it
    assert placement.sees(scene.mesh(), eye, c, r) == 1.0
    d = (c - eye) / np.linalg.norm(c - eye)
    assert Tracer(scene.mesh()).distance(eye[None], d[None])[0] > np.linalg.norm(c - eye)
