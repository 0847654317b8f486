"""Objects from mesh files (``object.shape = "mesh"``, ``object.file``) against independent answers: the shipped
mesh is what ``scripts/make_meshes.py`` makes; Embree's hits on the object equal Mitsuba's on the same triangles;
hit normals are the barycentric interpolation of the vertex normals (computed here with trimesh, not with
study's code); cache keys follow the file's bytes, not its path; bad files are one line naming file and key."""

import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import load_script

from study.errors import StudyError
from study.scene import camera_rays, load_scene_file, objects, scene_from_dict
from tests.conftest import scene_toml, small_scene_dict

ROOT = Path(__file__).resolve().parents[2]
BUNNY = ROOT / "scenes" / "meshes" / "bunny.obj"


CAMERA = {"eye": [-0.3, 1.7, -1.9], "target": [0.6, 1.2, 0.3], "fov": 35.0, "width": 40, "height": 40}


def mesh_scene(file=BUNNY, camera=CAMERA, **obj):
    d = small_scene_dict(camera=camera)
    d["object"] = {
        "shape": "mesh",
        "file": str(file),
        "center": [0.6, 1.2, 0.3],
        "radius": 0.4,
        "rotation": [0.0, -40.0, 0.0],
        "material": {"type": "mirror"},
        **obj,
    }
    return scene_from_dict(d)


def test_shipped_mesh_is_what_the_script_makes_and_small():
    made = load_script("make_meshes").files()
    assert set(made) == {p.name for p in (ROOT / "scenes" / "meshes").glob("bunny.*")}
    for name, text in made.items():
        assert (ROOT / "scenes" / "meshes" / name).read_text() == text
        assert len(text.encode()) < 200_000


def test_mesh_file_is_closed_unit_sized_and_smooth():
    """Closed and consistently wound; bounding radius 1 about its bounding-box centre; points 1% along each vertex
    normal lie outside (trimesh.contains), against it inside; neighbouring normals differ by < 50°."""
    m = objects.unit_shape("mesh", file=str(BUNNY))
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0
    assert np.linalg.norm(m.vertices, axis=1).max() == pytest.approx(1.0)
    assert np.allclose(m.bounds.sum(0), 0, atol=1e-12)
    n = np.asarray(m.vertex_normals)
    idx = np.random.default_rng(2).choice(len(m.vertices), 300, replace=False)
    assert not m.contains(m.vertices[idx] + 0.01 * n[idx]).any()
    assert m.contains(m.vertices[idx] - 0.01 * n[idx]).all()
    e = m.edges_unique
    assert np.degrees(np.arccos(np.clip(np.sum(n[e[:, 0]] * n[e[:, 1]], 1), -1, 1))).max() < 50


def test_object_scaled_rotated_and_placed():
    """World vertices lie within radius of center and reach it; a rotation by 90° about y maps x to −z."""
    sc = mesh_scene(radius=0.3, rotation=[0.0, 0.0, 0.0])
    om = objects.object_mesh(sc.object)
    r = np.linalg.norm(om.vertices - np.array(sc.object.center), axis=1)
    assert r.max() == pytest.approx(0.3)
    turned = objects.object_mesh(mesh_scene(radius=0.3, rotation=[0.0, 90.0, 0.0]).object)
    c = np.array(sc.object.center)
    assert np.allclose((om.vertices - c)[:, 0], -(turned.vertices - c)[:, 2], atol=1e-9)


def test_embree_and_mitsuba_hit_the_same_mesh_with_the_same_normals():
    """Camera rays against Mitsuba's scene (room and the bunny) and the object's own Embree scene: the same rays
    hit the object, at the same distance (1e-4 m) with the same shading normal (0.5°)."""
    from study.reference.mitsuba import mi, scene_dict
    from study.reference.mitsuba import sensor as _sensor

    m = mi()
    sc = mesh_scene()
    c = sc.camera
    msc = m.load_dict(
        scene_dict(
            sc, with_object=True, sensor=_sensor(c.eye, c.target, c.up, c.fov, c.width, c.height, 1, 0)
        )
    )
    o, d = (a.reshape(-1, 3) for a in camera_rays(c, 1))
    si = msc.ray_intersect(m.Ray3f(m.Point3f(*o.T.astype(np.float32)), m.Vector3f(*d.T.astype(np.float32))))
    h = objects.object_geometry(sc).hits(o, d)
    ours = np.isfinite(h["t"])
    theirs = np.isclose(np.array(si.t), h["t"], atol=1e-4)
    assert ours.sum() > 100 and np.array_equal(ours, theirs)
    n_m = np.stack([np.array(v) for v in (si.sh_frame.n.x, si.sh_frame.n.y, si.sh_frame.n.z)], -1)[ours]
    ang = np.degrees(np.arccos(np.clip(np.sum(n_m * h["normal"][ours], 1), -1, 1)))
    assert ang.max() < 0.5, ang.max()


def test_hit_normals_are_interpolated_vertex_normals():
    """At each hit: the barycentric coordinates of the hit point in its triangle (trimesh), times the vertex
    normals, normalised, equal the normal Embree's geometry returns (1e-3); flat (geometric) normals would not:
    they differ from these by more than 2° on many hits."""
    import trimesh

    sc = mesh_scene(camera={**CAMERA, "width": 16, "height": 16})
    g = objects.object_geometry(sc)
    o, d = (a.reshape(-1, 3) for a in camera_rays(sc.camera, 1))
    h = g.hits(o, d)
    hit = np.isfinite(h["t"])
    p = o[hit] + d[hit] * h["t"][hit, None]
    T = g.mesh.vertices[g.mesh.faces]  # brute force: the nearest triangle of each point
    P = np.repeat(p, len(T), axis=0)
    near = trimesh.triangles.closest_point(np.tile(T, (len(p), 1, 1)), P)
    tri = np.linalg.norm(near - P, axis=1).reshape(len(p), len(T)).argmin(1)
    bary = trimesh.triangles.points_to_barycentric(T[tri], p)
    n = np.einsum("nk,nkj->nj", bary, g.mesh.normals[g.mesh.faces[tri]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs(n - h["normal"][hit]).max() < 1e-3
    flat = np.degrees(np.arccos(np.clip(np.sum(h["geometric"][hit] * n, 1), -1, 1)))
    assert (flat > 2).mean() > 0.1


def test_relative_file_resolves_against_the_scene_file(tmp_path, monkeypatch):
    (tmp_path / "scenes" / "m").mkdir(parents=True)
    shutil.copy(BUNNY, tmp_path / "scenes" / "m" / "b.obj")
    d = small_scene_dict()
    d["object"] = {"file": "m/b.obj", "center": [0.6, 1.2, 0.3], "radius": 0.4}  # shape "mesh" implied
    (tmp_path / "scenes" / "s.toml").write_text(scene_toml(d))
    monkeypatch.chdir(tmp_path)  # not the scene's directory
    sc = load_scene_file("scenes/s.toml")
    assert sc.object.shape == "mesh" and sc.object.file == str(tmp_path / "scenes" / "m" / "b.obj")
    assert sc.with_updates({"object.radius": 0.3}).object.file == sc.object.file  # stays absolute


@pytest.mark.parametrize(
    "obj, words",
    [
        ({"shape": "mesh"}, 'object.file: a mesh file .* for shape "mesh", and only for it'),
        ({"shape": "torus", "file": "BUNNY"}, "object.file: a mesh file .*shape .torus."),
        ({"shape": "mesh", "file": "nowhere/x.obj"}, "object.file: .*no such file: .*nowhere/x.obj"),
        (
            {"shape": "mesh", "file": "scene.toml"},
            "object.file: a mesh file \\(.obj, .ply.*file .*scene.toml",
        ),
    ],
)
def test_bad_object_files_are_one_line(tmp_path, obj, words):
    d = small_scene_dict()
    shutil.copy(BUNNY, tmp_path / "bunny.obj")  # beside the scene file: a scene names files in its folder
    d["object"] = {k: ("bunny.obj" if v == "BUNNY" else v) for k, v in obj.items()}
    (tmp_path / "scene.toml").write_text(scene_toml(d))
    with pytest.raises(StudyError, match=words) as e:
        load_scene_file(tmp_path / "scene.toml")
    assert str(tmp_path / "scene.toml") in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize(
    "name, text, words",
    [
        ("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "holds no faces"),
        ("empty.stl", "", "unreadable mesh file|holds no faces"),
        ("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "no faces of non-zero area"),
        ("junk.ply", "ply\nformat nonsense\n\x00\x01", "unreadable mesh file"),
    ],
)
def test_unusable_mesh_files_are_one_line(tmp_path, name, text, words):
    (tmp_path / name).write_text(text)
    sc = mesh_scene(tmp_path / name)
    with pytest.raises(StudyError, match=f"{tmp_path / name}: object.file: .*({words})") as e:
        objects.object_geometry(sc)
    assert "\n" not in str(e.value)


def test_cache_key_follows_the_file_bytes_not_its_path(tmp_path):
    """The key of Mitsuba's render with the object: equal for two copies of one file under other names, different
    once a byte of the file changes (a comment line: the geometry is the same, the key still follows the bytes)."""
    from study.measure.case import camera_render

    class Keys:
        def __init__(self):
            self.keys = []

        def get(self, kind, key, fn, code=None):
            self.keys.append(key)
            return np.zeros((40, 40, 3), np.float32)

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    shutil.copy(BUNNY, tmp_path / "a" / "x.obj")
    shutil.copy(BUNNY, tmp_path / "b" / "y.obj")
    spy = Keys()
    for f in (tmp_path / "a" / "x.obj", tmp_path / "b" / "y.obj"):
        camera_render(mesh_scene(f), spy, with_object=True)
    (tmp_path / "b" / "y.obj").write_text(BUNNY.read_text() + "# one more byte\n")
    camera_render(mesh_scene(tmp_path / "b" / "y.obj"), spy, with_object=True)
    camera_render(mesh_scene(tmp_path / "b" / "y.obj", radius=0.35), spy, with_object=True)
    k = spy.keys
    assert k[0] == k[1] and k[2] != k[1] and k[3] != k[2]


def test_mesh_object_case_end_to_end(tmp_path):
    """A small case with the bunny: every method row finite; localized(10) shows the exact hits (median angle
    < 0.5°), classical does not (> 1°)."""
    from study import methods
    from study.cache import Cache
    from study.measure.case import run_case

    d = small_scene_dict(camera={**CAMERA, "width": 32, "height": 32})
    d["object"] = {
        "file": str(BUNNY),
        "center": [0.6, 1.2, 0.3],
        "radius": 0.4,
        "rotation": [0.0, -40.0, 0.0],
        "material": {"type": "mirror"},
    }
    d["render"].update(cube_res=16)
    case = run_case(
        scene_from_dict(d),
        [methods.make("classical"), methods.make("localized", iterations=10)],
        cache=Cache(tmp_path),
    )
    by = {r["label"]: r for r in case.rows}
    assert all(np.isfinite(r["angle_median_deg"]) and np.isfinite(r["rmse_truth"]) for r in case.rows)
    assert by["localized(iterations=10)"]["angle_median_deg"] < 0.5
    assert by["classical"]["angle_median_deg"] > 1
