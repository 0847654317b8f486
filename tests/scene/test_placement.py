"""Automatic placement (study.scene.autoplace) and its checks (study.scene.placement) by Embree (issue 26): exact
against brute force, only for the keys the user left out, the same for a mesh path and a TOML naming the mesh, a
camera that sees the object unblocked, and errors that never blame a key the user did not set."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import study
from study.errors import StudyError
from study.scene import autoplace, placement, scene_from_dict
from study.scene.environment import geometry

ROOT = Path(__file__).resolve().parents[2]
ROOM = ROOT / "tests" / "assets" / "neg_room.obj"


def write_obj(path: Path, V: np.ndarray, F: np.ndarray) -> Path:
    path.write_text(
        "".join(f"v {x:.6g} {y:.6g} {z:.6g}\n" for x, y, z in V)
        + "".join(f"f {a} {b} {c}\n" for a, b, c in F + 1)
    )
    return path


def cornell_obj(tmp_path) -> Path:
    """Mitsuba's Cornell box (open front, two blocks) as a plain OBJ: no sensor comes with it."""
    mesh = geometry({"type": "mitsuba", "builtin": "cornell_box"}).mesh
    return write_obj(tmp_path / "cornell.obj", mesh.vertices.astype(float), mesh.faces)


def test_embree_cast_and_clearance_agree_with_brute_force():
    from trimesh.triangles import closest_point

    mesh = geometry({"type": "mitsuba", "builtin": "cornell_box"}).mesh
    rng = np.random.default_rng(0)
    o = rng.uniform(-0.9, 0.9, (50, 3))
    d = placement.directions(64)
    tri = mesh.vertices[mesh.faces].astype(float)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    for p in o[:10]:
        t, front = placement.cast(mesh, p[None], d)
        # brute force Möller–Trumbore
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        q = np.cross(d[:, None], e2)
        det = np.sum(e1 * q, -1)
        s = p - tri[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.sum(s * q, -1) / det
            r = np.cross(s, e1)
            v = np.sum(d[:, None] * r, -1) / det
            tt = np.sum(e2 * r, -1) / det
        ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (tt > 1e-6)
        tt = np.where(ok, tt, np.inf)
        k = tt.argmin(1)
        want = tt[np.arange(len(d)), k]
        np.testing.assert_allclose(t, want, rtol=1e-4)
        hit = np.isfinite(want)
        assert np.array_equal(front[hit], (np.sum(n[k] * d, -1) < 0)[hit])
        exact = np.linalg.norm(closest_point(tri, np.broadcast_to(p, tri.shape[:1] + (3,))) - p, axis=1).min()
        assert placement.clearance(mesh, p) == pytest.approx(exact, rel=1e-9)


def test_a_mesh_path_and_a_toml_naming_it_place_alike(tmp_path):
    (tmp_path / ROOM.name).symlink_to(ROOM)  # a scene names files in its folder (a symlink put there)
    (tmp_path / "s.toml").write_text(f'[environment]\ntype = "mesh"\nfile = "{ROOM.name}"\n')
    a, b = study.load_scene(ROOM), study.load_scene(tmp_path / "s.toml")
    assert a.model_dump() == b.model_dump()
    c = study.load_scene(ROOM, {"object.radius": 0.2})
    d = study.load_scene(tmp_path / "s.toml", {"object.radius": 0.2})
    assert c.model_dump() == d.model_dump() and c.object.radius == 0.2


def test_placement_is_skipped_for_every_key_the_user_gives(monkeypatch):
    full = {
        "environment": {"type": "mesh", "file": str(ROOM)},
        "reference": {"point": [0.0, 1.5, 0.0]},
        "object": {"center": [0.5, 1.0, 0.3], "radius": 0.3},
        "camera": {"eye": [0.0, 1.5, -1.8], "target": [0.5, 1.0, 0.3], "up": [0, 1, 0], "fov": 60.0},
        "light": {"position": [0, 2.5, 0], "intensity": [5, 5, 5], "enabled": True},
    }

    def boom(*a, **k):
        raise AssertionError("suggested although given")

    monkeypatch.setattr(autoplace, "suggest", boom)
    scene = scene_from_dict(full)
    assert scene.suggested_keys() == frozenset()
    monkeypatch.undo()
    monkeypatch.setattr(autoplace, "_reference", boom)
    monkeypatch.setattr(autoplace, "_eye", boom)
    part = {**full, "camera": {"eye": [0.0, 1.5, -1.8]}, "object": {"radius": 0.3}}
    scene = scene_from_dict(part)  # no grid search, no camera search: only the centre, target and up
    assert scene.suggested_keys() == {"object.center", "camera.target", "camera.up"}
    assert scene.camera.eye == (0.0, 1.5, -1.8) and scene.reference.point == (0.0, 1.5, 0.0)


def test_the_suggested_camera_sees_the_object_unblocked(tmp_path):
    from study.reference.embree import Tracer

    for path in (cornell_obj(tmp_path), ROOM):
        scene = study.load_scene(path)
        eye, c, r = map(np.asarray, (scene.camera.eye, scene.object.center, scene.object.radius))
        assert placement.sees(scene.mesh(), eye, c, float(r)) == 1.0, path.name
        d = c - eye
        t = Tracer(scene.mesh()).distance(eye[None], (d / np.linalg.norm(d))[None])
        assert t[0] > np.linalg.norm(d) - r, path.name  # nothing between the eye and the object


def test_a_failing_suggestion_blames_the_placement_not_an_unset_key(monkeypatch):
    with pytest.raises(StudyError) as e:
        study.load_scene(ROOM, {"object.radius": 1.6})  # too big for the room: no spot for the centre
    msg = str(e.value)
    assert ": environment: automatic placement found no spot for object.center" in msg, msg
    assert "set object.center yourself" in msg and "\n" not in msg
    real = autoplace.suggest

    def bad_eye(env, given=None):  # a suggestion that fails a check: the eye inside the object
        out = real(env, given)
        return {**out, "camera.eye": out["object.center"]}

    monkeypatch.setattr(autoplace, "suggest", bad_eye)
    with pytest.raises(StudyError) as e:
        study.load_scene(ROOM)
    msg = str(e.value)
    assert ": environment: automatic placement failed: the suggested camera.eye lies inside the object" in msg
    assert "set camera.eye yourself" in msg, msg
    monkeypatch.undo()
    with pytest.raises(StudyError) as e:  # a key the user set is named as it is
        study.load_scene(ROOM, {"reference.point": [0.0, 5.0, 0.0]})
    assert ": reference.point:" in str(e.value) and "automatic" not in str(e.value)


def test_an_override_keeps_the_other_suggestions_suggested():
    scene = study.load_scene(ROOM)
    moved = scene.with_updates({"camera.width": 32})
    assert moved.suggested_keys() == scene.suggested_keys()
    assert "camera.eye" not in scene.with_updates({"camera.eye": [0.0, 1.5, -1.8]}).suggested_keys()


def test_the_placement_benchmark_runs():
    out = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "bench_placement.py"), "--triangles", "20000"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "placement (suggest every key + checks)" in out.stdout
