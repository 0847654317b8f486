"""Hostile scene files (issue 40): nothing read outside the scene's folder, no hang, no internal error — each break
of the hostile-testing round reproduced, now one line naming the file and the element, exit 2, and not one byte
read from outside (the reads are recorded)."""

import builtins
import json
import os
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from study.errors import BAD_INPUT, StudyError
from study.scene.environment import geometry
from study.scene.sources import key_fields

ROOT = Path(__file__).resolve().parents[2]
ASSETS = ROOT / "tests" / "assets"


@pytest.fixture
def layout(tmp_path):
    """scene/ (where the file under test lies) beside secret/ (what it must not read)."""
    from PIL import Image

    scene, secret = tmp_path / "scene", tmp_path / "secret"
    scene.mkdir(), secret.mkdir()
    (secret / "room.bin").write_bytes((ASSETS / "room.bin").read_bytes())
    Image.fromarray(np.full((2, 2, 3), 255, np.uint8)).save(secret / "tex.png")
    (secret / "x.mtl").write_text("newmtl m\nKd 1 0 0\n")
    (scene / "wall.png").write_bytes((ASSETS / "wall.png").read_bytes())
    (scene / "room.bin").write_bytes((ASSETS / "room.bin").read_bytes())
    return scene, secret


@pytest.fixture
def reads(monkeypatch):
    """Every path opened through Python's open while the test runs."""
    seen: list[str] = []
    real = builtins.open

    def spy(file, *a, **k):
        if isinstance(file, str | os.PathLike):
            seen.append(os.path.abspath(os.fspath(file)))
        return real(file, *a, **k)

    monkeypatch.setattr(builtins, "open", spy)
    import io

    monkeypatch.setattr(io, "open", spy)
    return seen


def refused(env: dict, *words: str) -> str:
    """The one-line StudyError of loading ``env`` (its content key first, as a run computes it), with ``words``."""
    t = time.perf_counter()
    with pytest.raises(StudyError) as e:
        key_fields({"environment": env})
        geometry(env)
    msg = str(e.value)
    assert e.value.code == BAD_INPUT and "\n" not in msg, msg
    assert all(w in msg for w in words), msg
    assert time.perf_counter() - t < 20, "took too long"
    return msg


def gltf_with(scene: Path, **change) -> Path:
    g = json.loads((ASSETS / "room.gltf").read_text())
    for k, v in change.items():
        if callable(v):
            v(g)
        else:
            g[k] = v
    p = scene / "room.gltf"
    p.write_text(json.dumps(g))
    return p


def set_buffer_uri(uri):
    return lambda g: g["buffers"][0].__setitem__("uri", uri)


def set_image_uri(uri):
    return lambda g: g["images"][0].__setitem__("uri", uri)


# ---------------------------------------------------------------------------------------------- outside the folder
@pytest.mark.parametrize(
    "change, words",
    [
        (lambda s: set_buffer_uri("../secret/room.bin"), ["buffer 0", "leaves the scene's folder"]),
        (lambda s: set_buffer_uri("%2e%2e/secret/room.bin"), ["buffer 0", "leaves the scene's folder"]),
        (lambda s: set_buffer_uri("/etc/passwd"), ["buffer 0", "absolute path"]),
        (lambda s: set_buffer_uri("file:///etc/passwd"), ["buffer 0", "scheme"]),
        (lambda s: set_image_uri("../secret/tex.png"), ["image 0", "leaves the scene's folder"]),
        (lambda s: set_image_uri(str(s / "tex.png")), ["image 0", "absolute path"]),
    ],
)
def test_gltf_uris_outside_the_folder_are_refused_before_any_byte_is_read(layout, reads, change, words):
    scene, secret = layout
    p = gltf_with(scene, _=change(secret))
    refused({"type": "mesh", "file": str(p)}, *words)
    assert not [r for r in reads if r.startswith(str(secret)) or r == "/etc/passwd"], reads


@pytest.mark.parametrize(
    "obj, mtl, words",
    [
        ("mtllib ../secret/x.mtl\n", None, ["line 1: mtllib", "leaves the scene's folder"]),
        ("mtllib /etc/passwd\n", None, ["line 1: mtllib", "absolute path"]),
        ("mtllib m.mtl\n", "newmtl m\nmap_Kd ../secret/tex.png\n", ["m.mtl line 2: map_Kd", "leaves"]),
        ("mtllib m.mtl\n", "newmtl m\nmap_Kd SECRET_ABS\n", ["m.mtl line 2: map_Kd", "absolute path"]),
    ],
)
def test_obj_and_mtl_files_outside_the_folder_are_refused_before_any_byte_is_read(
    layout, reads, obj, mtl, words
):
    scene, secret = layout
    if mtl:
        (scene / "m.mtl").write_text(mtl.replace("SECRET_ABS", str(secret / "tex.png")))
    (scene / "o.obj").write_text(obj + "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl m\nf 1/1 2/1 3/1\n")
    refused({"type": "mesh", "file": str(scene / "o.obj")}, *words)
    assert not [r for r in reads if r.startswith(str(secret)) or r == "/etc/passwd"], reads


def test_an_mtl_in_a_subfolder_may_name_a_texture_beside_it_under_the_scene_folder(layout):
    """The folder is the one of the file the user named: asset packs keep materials/ and textures/ side by side."""
    scene, _ = layout
    (scene / "materials").mkdir(), (scene / "textures").mkdir()
    (scene / "textures" / "w.png").write_bytes((ASSETS / "wall.png").read_bytes())
    (scene / "materials" / "m.mtl").write_text("newmtl m\nmap_Kd ../textures/w.png\n")
    (scene / "o.obj").write_text(
        "mtllib materials/m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl m\nf 1/1 2/1 3/1\n"
    )
    env = geometry({"type": "mesh", "file": str(scene / "o.obj")})
    assert env.parts[0].albedo is not None


def test_a_symlink_the_user_placed_in_the_folder_may_point_anywhere(layout):
    scene, secret = layout
    (scene / "linked.bin").symlink_to(secret / "room.bin")
    p = gltf_with(scene, _=set_buffer_uri("linked.bin"))
    assert len(geometry({"type": "mesh", "file": str(p)}).mesh.faces) > 0


def test_symlink_loops_are_one_line(layout):
    scene, _ = layout
    (scene / "a.bin").symlink_to(scene / "b.bin")
    (scene / "b.bin").symlink_to(scene / "a.bin")
    refused(
        {"type": "mesh", "file": str(gltf_with(scene, _=set_buffer_uri("a.bin")))}, "buffer 0", "symlink loop"
    )
    (scene / "env.obj").symlink_to(scene / "env.obj")
    from study.scene import scene_from_dict

    with pytest.raises(StudyError, match="environment.file: a symlink loop") as e:
        scene_from_dict({"environment": {"type": "mesh", "file": str(scene / "env.obj")}}, source="s.toml")
    assert "\n" not in str(e.value)


def test_mitsuba_xml_filenames_outside_the_folder_are_refused_before_mitsuba_reads(layout):
    scene, secret = layout
    (secret / "b.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (scene / "inc.xml").write_text(
        '<scene version="3.0.0"><shape type="obj" filename="../secret/b.obj"/></scene>'
    )
    (scene / "s.xml").write_text(
        '<scene version="3.0.0"><shape type="cube"/><include filename="inc.xml"/></scene>'
    )
    refused(
        {"type": "mitsuba", "file": str(scene / "s.xml")},
        "inc.xml: <shape> names '../secret/b.obj'",
        "outside",
    )


# ---------------------------------------------------------------------------------------------- structure
@pytest.mark.parametrize(
    "doc, words",
    [
        ([1, 2], "its JSON is a list, not an object"),
        ("room", "its JSON is a str"),
        (7, "its JSON is a int"),
        ({"asset": {"version": "2.0"}, "buffers": [1, 2]}, "'buffers' must be an array of objects"),
        ({"asset": {"version": "2.0"}, "nodes": {"a": 1}}, "'nodes' must be an array of objects"),
        ({"asset": {"version": "2.0"}, "scene": "x"}, "'scene' must be an index"),
        ({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"children": [0]}]},
         "node 0 is reached twice"),
        ({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"children": [1]}, {"children": [0]}]},
         "node 0 is reached twice"),
        ({"asset": {"version": "2.0"}, "scenes": [{"nodes": [5]}], "nodes": []}, "nodes index 5 is out of range"),
        ({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 3}]}, "meshes index 3 is out"),
    ],
)  # fmt: skip
def test_gltf_structure_is_checked_before_use(tmp_path, doc, words):
    (tmp_path / "s.gltf").write_text(json.dumps(doc))
    refused({"type": "mesh", "file": str(tmp_path / "s.gltf")}, words)


def test_json_nested_200000_deep_is_one_line(tmp_path):
    (tmp_path / "s.gltf").write_text("[" * 200_000 + "]" * 200_000)
    refused({"type": "mesh", "file": str(tmp_path / "s.gltf")}, "nested too deeply")


def test_truncated_files_are_one_line(tmp_path):
    p = ASSETS / "room.gltf"
    g = json.loads(p.read_text())
    (tmp_path / "room.bin").write_bytes((ASSETS / "room.bin").read_bytes()[:100])
    (tmp_path / "wall.png").write_bytes((ASSETS / "wall.png").read_bytes())
    (tmp_path / "room.gltf").write_text(json.dumps(g))
    refused({"type": "mesh", "file": str(tmp_path / "room.gltf")}, "buffer 0 holds 100 bytes", "truncated")
    from tests.scene.test_real_files import TRI_F, TRI_V, gltf_doc, write_glb

    glb = write_glb(tmp_path / "t.glb", *gltf_doc(TRI_V, TRI_F)).read_bytes()
    (tmp_path / "cut.glb").write_bytes(glb[: len(glb) - 30])
    refused({"type": "mesh", "file": str(tmp_path / "cut.glb")}, "truncated")


def test_an_accessor_past_its_buffer_view_is_one_line(tmp_path):
    from tests.scene.test_real_files import TRI_F, TRI_V, gltf_doc, write_glb

    g, blob = gltf_doc(TRI_V, TRI_F)
    g["accessors"][0]["count"] = 400
    refused(
        {"type": "mesh", "file": str(write_glb(tmp_path / "a.glb", g, blob))}, "accessor 0", "past the end"
    )


def bomb_png(path: Path) -> Path:
    """A 15 000² 1-bit PNG: a few kB on disk, 225 M pixels decoded."""
    import zlib

    w = h = 15_000
    row = b"\0" + b"\0" * (w // 8 + 1)
    raw = zlib.compress(row * h, 9)
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))  # noqa: E731
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 1, 0, 0, 0, 0))
                     + chunk(b"IDAT", raw) + chunk(b"IEND", b""))  # fmt: skip
    return path


def test_decompression_bombs_are_one_line_via_gltf_and_mtl(layout):
    scene, _ = layout
    bomb_png(scene / "wall.png")
    refused({"type": "mesh", "file": str(gltf_with(scene))}, "image 0", "decompression-bomb")
    (scene / "m.mtl").write_text("newmtl m\nmap_Kd wall.png\n")
    (scene / "o.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl m\nf 1/1 2/1 3/1\n")
    refused({"type": "mesh", "file": str(scene / "o.obj")}, "map_Kd wall.png", "decompression-bomb")


# ---------------------------------------------------------------------------------------------- values
def set_material(k, v):
    return lambda g: g["materials"][0].setdefault("pbrMetallicRoughness", {}).__setitem__(k, v)


def set_light(**li):
    return lambda g: g["extensions"]["KHR_lights_punctual"]["lights"][0].update(li)


@pytest.mark.parametrize(
    "change, words",
    [
        (set_material("baseColorFactor", [-1, 0, 0, 1]), "baseColorFactor must be 4 number(s) in [0, 1]"),
        (set_material("baseColorFactor", [5, 5, 5, 1]), "baseColorFactor must be 4 number(s) in [0, 1]"),
        (set_light(intensity=-10), "intensity must be 1 number(s) in ≥ 0"),
        (set_light(type="spot", spot={"innerConeAngle": -1.0}), "0 ≤ innerConeAngle < outerConeAngle ≤ π/2"),
        (set_light(type="spot", spot={"outerConeAngle": 2.0}), "0 ≤ innerConeAngle < outerConeAngle ≤ π/2"),
    ],
)
def test_material_factors_and_lights_outside_the_spec_ranges_are_refused(layout, change, words):
    scene, _ = layout
    refused({"type": "mesh", "file": str(gltf_with(scene, _=change))}, words)


# ------------------------------------------------------------------------------------ the CLI, and random input
def test_the_cli_exits_2_with_one_line_for_a_hostile_file(layout):
    scene, _ = layout
    p = gltf_with(scene, _=set_buffer_uri("../secret/room.bin"))
    cmd = [
        sys.executable,
        "-m",
        "study.cli",
        "run",
        str(p),
        "-m",
        "classical",
        "--out",
        str(scene.parent / "o"),
    ]
    out = subprocess.run(cmd, capture_output=True, text=True, cwd=scene.parent, timeout=600)
    assert out.returncode == 2, out.stderr[-2000:]
    lines = [ln for ln in out.stderr.splitlines() if "leaves the scene's folder" in ln]
    assert len(lines) == 1 and "Traceback" not in out.stderr, out.stderr[-2000:]
    assert not (scene.parent / "o").exists()


def _only_study_errors(path: Path, env: dict):
    try:
        geometry(env)
    except StudyError as err:
        assert "\n" not in str(err)


def _paths(v, at=()):
    """Every path into a JSON value (keys and indices), the value's own first."""
    yield at
    items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
    for k, x in items:
        yield from _paths(x, (*at, k))


def test_random_gltf_structures_never_crash_or_hang(layout):
    """The test room's glTF with 1–3 of its members (any depth) replaced by random JSON — a wrong type, a bad
    index, a nested list — bounded in time: the reader answers or refuses in one line, never an internal error."""
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    scene, _ = layout
    base = json.loads((ASSETS / "room.gltf").read_text())
    paths = [p for p in _paths(base) if p]
    leaf = st.one_of(st.none(), st.booleans(), st.integers(-3, 70), st.floats(allow_nan=True),
                     st.sampled_from(["2.0", "VEC3", "SCALAR", "data:,", "x.bin", "../x", "spot", ""]))  # fmt: skip
    grow = lambda c: (
        st.lists(c, max_size=3) | st.dictionaries(st.sampled_from(["uri", "nodes", "index"]), c, max_size=3)
    )  # noqa: E731
    value = st.recursive(leaf, grow, max_leaves=8)

    @settings(
        max_examples=300,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        database=None,
        derandomize=True,
    )
    @given(st.lists(st.tuples(st.sampled_from(paths), value), min_size=1, max_size=3))
    def check(changes):
        g = json.loads(json.dumps(base))
        for path, v in changes:
            node = g
            try:
                for k in path[:-1]:
                    node = node[k]
                node[path[-1]] = v
            except (KeyError, IndexError, TypeError):
                continue  # an earlier change removed this path
        (scene / "room.gltf").write_text(json.dumps(g))
        _only_study_errors(scene / "room.gltf", {"type": "mesh", "file": str(scene / "room.gltf")})

    check()


def test_random_obj_lines_never_crash_or_hang(tmp_path):
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    tok = st.one_of(st.sampled_from(["v", "vt", "vn", "f", "usemtl", "mtllib", "o", "g", "l", "#", "\\", "/", "//"]),
                    st.integers(-5, 8).map(str), st.sampled_from(["1/1", "2//2", "3/3/3", "-1", "9" * 25, "nan",
                                                                 "1e999", "a.mtl", "../x.mtl"]))  # fmt: skip
    line = st.lists(tok, min_size=0, max_size=6).map(lambda t: " \t"[len(t) % 2].join(t))
    body = st.lists(line, max_size=25).map(lambda ls: "v 0 0 0\nv 1 0 0\nv 0 1 0\n" + "\n".join(ls) + "\n")

    @settings(
        max_examples=200,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        database=None,
        derandomize=True,
    )
    @given(body)
    def check(text):
        (tmp_path / "r.obj").write_text(text)
        _only_study_errors(tmp_path / "r.obj", {"type": "mesh", "file": str(tmp_path / "r.obj")})

    check()


def test_a_mitsuba_path_element_cannot_bring_in_a_file_from_outside(layout):
    """``<path value="../secret"/>`` adds a folder to Mitsuba's search: a name that is not in the scene's folder
    would be found there. Such a name is refused before Mitsuba reads; a ``<path>`` that brings nothing is harmless."""
    scene, secret = layout
    (secret / "b.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (scene / "s.xml").write_text('<scene version="3.0.0"><path value="../secret"/><shape type="cube"/>'
                                 '<shape type="obj" filename="b.obj"/></scene>')  # fmt: skip
    refused(
        {"type": "mitsuba", "file": str(scene / "s.xml")}, "s.xml: <shape> names 'b.obj'", "not in the scene"
    )
    (scene / "s.xml").write_text(
        '<scene version="3.0.0"><path value="../secret"/><shape type="cube"/></scene>'
    )
    assert len(geometry({"type": "mitsuba", "file": str(scene / "s.xml")}).mesh.faces) == 12
