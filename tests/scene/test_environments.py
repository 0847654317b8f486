"""Environment sources behind one interface (study.scene.environment): the box room, mesh files and Mitsuba scenes
(builtin dict, Python dict, XML), open environments, and placement by ray casting.

Each source is checked against something independent: Embree's and Mitsuba's hits of the same rays agree (the
triangles are the very ones Mitsuba renders), a small case runs end to end with finite images, and placement
errors name the key.
"""

from pathlib import Path

import numpy as np
import pytest
from conftest import small_scene_dict

from study.cache import Cache
from study.errors import StudyError
from study.impostor import cubemap
from study.impostor.capture import capture_distance
from study.measure.case import run_case
from study.methods import make
from study.reference.embree import Tracer
from study.reference.mitsuba import mi, scene_dict, sensor
from study.scene import load_scene_file, scene_from_dict
from study.scene.environment import geometry
from study.scene.sources import key_fields

ROOT = Path(__file__).resolve().parents[2]
TINY = {
    "render.cube_res": 16,
    "render.cube_spp": 2,
    "render.spp": 2,
    "camera.width": 32,
    "camera.height": 32,
    "render.supersample": 1,
    "render.max_depth": 3,
}

CORNELL = {
    "environment": {"type": "mitsuba", "builtin": "cornell_box"},
    "reference": {"point": [0.0, 0.45, 0.0]},
    "object": {"center": [0.35, -0.18, 0.45], "radius": 0.2, "material": {"type": "mirror"}},
    "camera": {"eye": [0.0, 0.0, 3.9], "target": [0.0, 0.0, 0.0], "fov": 39.3, "width": 32, "height": 32},
    "render": {"cube_res": 16, "cube_spp": 2, "spp": 2, "supersample": 1, "max_depth": 3},
}

#: a Mitsuba XML scene nobody here wrote the loader for: a room of rectangles open at +z, a cube, an area light
XML = """<scene version="3.0.0">
  <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.6, 0.6, 0.6"/></bsdf>
  <shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/><translate y="-1"/>
    </transform><ref id="grey"/></shape>
  <shape type="rectangle" id="back"><transform name="to_world"><translate z="-1"/></transform><ref id="grey"/></shape>
  <shape type="rectangle" id="ceiling"><transform name="to_world"><rotate x="1" angle="90"/><translate y="1"/>
    </transform><ref id="grey"/></shape>
  <shape type="rectangle" id="left"><transform name="to_world"><rotate y="1" angle="90"/><translate x="-1"/>
    </transform><bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.2, 0.2"/></bsdf></shape>
  <shape type="rectangle" id="right"><transform name="to_world"><rotate y="1" angle="-90"/><translate x="1"/>
    </transform><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.7, 0.2"/></bsdf></shape>
  <shape type="cube" id="block"><transform name="to_world"><scale value="0.25"/><translate x="-0.5" y="-0.75"/>
    </transform><ref id="grey"/></shape>
  <shape type="rectangle" id="lamp"><transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/>
    <translate y="0.98"/></transform><emitter type="area"><rgb name="radiance" value="10, 10, 10"/></emitter>
    <ref id="grey"/></shape>
</scene>
"""


def xml_scene(tmp_path, **over) -> dict:
    (tmp_path / "box.xml").write_text(XML)
    d = {**CORNELL, "environment": {"type": "mitsuba", "file": str(tmp_path / "box.xml")}}
    d.update(over)
    return d


def mesh_scene(name: str) -> dict:
    return load_scene_file(ROOT / "scenes" / f"{name}.toml").with_updates(TINY)


def sources(tmp_path):
    """(what, scene) for every kind of source."""
    return [
        ("box", scene_from_dict(small_scene_dict())),
        ("mesh PLY (face colours)", mesh_scene("l_room")),
        ("mesh OBJ (materials, texture)", mesh_scene("atrium")),
        ("Mitsuba builtin dict", scene_from_dict(CORNELL)),
        (
            "Mitsuba dict from Python",
            scene_from_dict({**CORNELL, "environment": {"type": "mitsuba", "scene": mi().cornell_box()}}),
        ),
        ("Mitsuba XML", scene_from_dict(xml_scene(tmp_path))),
    ]


# ---------------------------------------------------------------------------------------------- one interface
def test_embree_and_mitsuba_agree_on_every_source(tmp_path):
    """Rays from the reference point: Embree's hit distances on ``scene.mesh()`` equal Mitsuba's
    ``ray_intersect`` on the scene dict it renders (the environment's own shapes for Mitsuba scenes)."""
    m = mi()
    rng = np.random.default_rng(3)
    d = rng.normal(size=(4000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for what, scene in sources(tmp_path):
        o = np.asarray(scene.reference.point, float)
        t_embree = Tracer(scene.mesh()).distance(np.broadcast_to(o, d.shape), d)
        sc = m.load_dict(
            scene_dict(scene, with_object=False, sensor=sensor(o, o + [0, 0, 1], [0, 1, 0], 90, 4, 4, 1, 0))
        )
        si = sc.ray_intersect(
            m.Ray3f(
                m.Point3f(*np.broadcast_to(o, d.shape).T.astype(np.float32)),
                m.Vector3f(*d.T.astype(np.float32)),
            )
        )
        t_mitsuba = np.where(np.array(si.is_valid()), np.array(si.t), np.inf)
        assert np.array_equal(np.isfinite(t_embree), np.isfinite(t_mitsuba)), what
        fin = np.isfinite(t_embree)
        np.testing.assert_allclose(t_embree[fin], t_mitsuba[fin], rtol=1e-4, atol=1e-5, err_msg=what)


def test_materials_come_from_the_file():
    """The atrium's floor keeps its texture (map_Kd), its walls their MTL colour; the L room its face colours."""
    atrium = geometry(mesh_scene("atrium"))
    parts = dict(zip(atrium.mesh.surfaces, atrium.parts))
    floor = next(p for n, p in parts.items() if p.albedo is not None)
    assert floor.albedo.shape[-1] == 3 and floor.albedo.std() > 0.05  # a checker, not a colour
    assert sum(p.color is not None for p in atrium.parts) == 4
    lroom = geometry(mesh_scene("l_room"))
    assert lroom.mesh.colors is not None and len(np.unique(lroom.mesh.colors.round(3), axis=0)) >= 6


def test_case_runs_on_every_source(tmp_path):
    for what, scene in sources(tmp_path)[1:]:
        out = run_case(scene, [make("classical"), make("localized")], cache=Cache(tmp_path / "c"))
        assert np.isfinite(out.mitsuba).all() and np.isfinite(out.truth).all(), what
        for lab, img in out.images.items():
            assert np.isfinite(img).all(), (what, lab)
        loc = next(r for r in out.rows if r["method"] == "localized")
        assert loc["wrong_fraction"] < 0.6, what  # it does localize


def test_cache_keys_hash_file_contents_not_paths(tmp_path):
    src = (ROOT / "scenes" / "rooms" / "l_room.ply").read_bytes()
    a, b = tmp_path / "a.ply", tmp_path / "b.ply"
    a.write_bytes(src)
    b.write_bytes(src)
    ka = key_fields({"environment": {"file": str(a)}})
    assert ka == key_fields({"environment": {"file": str(b)}})  # same bytes, other path
    b.write_bytes(src.replace(b"2.8", b"2.9"))
    assert ka != key_fields({"environment": {"file": str(b)}})  # other bytes, same path


# ---------------------------------------------------------------------------------------------- open environments
def test_open_environment_stores_no_surface_and_escaping_rays_escape():
    """Cornell box: texel rays through the open front store FAR; a ray whose exact continuation leaves the scene
    is shown at infinity in its own direction (CORRECT) by the methods that search, never NaN."""
    scene = scene_from_dict(CORNELL)
    dist = capture_distance(scene, 16)
    assert (dist >= cubemap.FAR_MIN).mean() > 0.05 and (dist < 10).mean() > 0.5
    out = run_case(
        scene, [make(n) for n in ("classical", "localized", "linear_secant", "layered")], cache=Cache(None)
    )
    for r in out.rows:
        assert np.isfinite(r["angle_median_deg"]) and r["valid_fraction"] == 1.0, r["label"]
    for lab, img in out.images.items():
        assert np.isfinite(img).all(), lab


def test_open_environment_methods_on_a_half_open_box():
    """Analytic: a box with its +z side missing; rays from near the reference point towards +z leave the scene.
    The searching methods show them at infinity within a texel's angle (all that leave well inside the open side;
    near its edges the parallax between x and o decides, as for any wall); rays towards the walls are hit."""
    from study import backend as backends
    from study.impostor import analytic
    from study.impostor.envmap import EnvMap
    from study.impostor.views import Captured
    from study.measure import outcomes

    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    imp = analytic.box_impostor(64, lo, hi)
    dirs = cubemap.texel_directions(64)
    imp[..., 3] = np.where(
        dirs[..., 2] > np.abs(dirs[..., :2]).max(-1), cubemap.FAR, imp[..., 3]
    )  # face +z open
    B = backends.get("numpy")
    env = Captured(impostor=EnvMap(imp.astype(np.float32), B), open=True, fallback=True)
    rng = np.random.default_rng(2)
    x = rng.uniform(-0.2, 0.2, (3000, 3))
    R = rng.normal(size=(3000, 3))
    R /= np.linalg.norm(R, axis=1, keepdims=True)
    t = analytic.box_hit(x, R, lo, hi) - x
    t = np.linalg.norm(t, axis=1)
    exact = x + R * t[:, None]
    out_z = exact[:, 2] > 1 - 1e-6  # leaves through the open side
    inner = out_z & (np.abs(exact[:, :2]).max(1) < 0.7)  # … at least 0.3 m from its edges
    exact[out_z] = x[out_z] + R[out_z] * cubemap.FAR
    eps = outcomes.tolerance(np.zeros(3), exact, 64)
    for name in ("localized", "linear_secant", "layered"):
        tr = make(name).trace(B, env, B.vec(x), B.vec(R))
        shown = B.to_numpy(tr.shown).astype(float)
        assert np.isfinite(shown).all(), name
        cls = outcomes.classify(x, R, shown, exact, eps=eps).cls
        assert (cls[inner] == outcomes.CORRECT).mean() > 0.99, name  # escapes shown at infinity
        assert (cls[out_z] == outcomes.CORRECT).mean() > 0.85, name  # (parallax near the edges)
        assert (cls[~out_z] == outcomes.CORRECT).mean() > 0.9, name  # walls still found
        assert not np.any(
            (np.linalg.norm(shown[out_z], axis=1) < cubemap.FAR_MIN) & (cls[out_z] == outcomes.CORRECT)
        ), name  # never a finite "hit" there


# ---------------------------------------------------------------------------------------------- placement
@pytest.mark.parametrize(
    "over, key, words",
    [
        (
            {"reference": {"point": [0.0, 0.0, 1000.0]}},
            "reference.point",
            "sees no surface",
        ),  # open: 5 m is fine
        (
            {"reference": {"point": [0.335, -0.7, 0.38]}},
            "reference.point",
            "inside geometry",
        ),  # the small box
        (
            {"object": {"center": [0.0, -0.9, 0.3], "radius": 0.2}},
            "object.center",
            "intersects the environment",
        ),
        (
            {
                "environment": {
                    "type": "mitsuba",
                    "scene": {
                        "type": "scene",
                        "g": {"type": "shapegroup", "r": {"type": "rectangle"}},
                        "i": {"type": "instance", "shapegroup": {"type": "ref", "id": "g"}},
                    },
                }
            },
            "environment",
            "shape 'i' (Instance) is not a triangle mesh",
        ),
        ({"environment": {"type": "mitsuba"}}, "environment", "exactly one"),
        ({"environment": {"type": "mesh", "file": "no/such.obj"}}, "environment.file", "no such file"),
        (
            {
                "environment": {"type": "mitsuba", "builtin": "cornell_box"},
                "columns": [{"center": [0.0, 0.0], "footprint": [0.1, 0.1], "height": 0.5}],
            },
            "columns",
            "box room",
        ),
    ],
)
def test_placement_errors_name_the_key(over, key, words):
    with pytest.raises(StudyError) as e:
        scene_from_dict({**CORNELL, **over}, source="s.toml")
    msg = str(e.value)
    assert msg.startswith(f"s.toml: {key}:") and words in msg and "\n" not in msg, msg


def test_mesh_without_faces_is_one_line(tmp_path):
    (tmp_path / "empty.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(StudyError) as e:
        scene_from_dict({**CORNELL, "environment": {"type": "mesh", "file": str(tmp_path / "empty.obj")}})
    assert "environment.file" in str(e.value) and "no faces" in str(e.value)


def test_relative_file_resolves_against_the_scene_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # not the repo: the path is the TOML's
    s = load_scene_file(ROOT / "scenes" / "l_room.toml")
    assert Path(s.environment.file) == ROOT / "scenes" / "rooms" / "l_room.ply"


def test_camera_outside_the_room_sees_the_object_and_a_wall_hides_it(tmp_path):
    """The Cornell camera stands outside the box (allowed); behind the back wall it sees no object pixel."""
    scene = scene_from_dict(CORNELL)
    assert np.asarray(scene.camera.eye)[2] > 1  # outside the box
    hidden = scene.with_updates({"camera.eye": [0.0, 0.0, -3.0]})  # behind the back wall
    with pytest.raises(StudyError) as e:
        run_case(hidden, [make("classical")], cache=Cache(None))
    assert "pixel" in str(e.value) and e.value.key == "object.center"


def test_proxies_use_the_bounds_or_the_given_box():
    from study.measure.inputs import env_info

    scene = scene_from_dict(CORNELL)
    lo, hi = env_info(scene)["room"]
    np.testing.assert_allclose(lo, [-1, -1.01, -1], atol=1e-5)  # the box's triangles' bounds
    np.testing.assert_allclose(hi, [1, 1, 1], atol=1e-5)
    boxed = scene.with_updates({"reference.box": [[-0.9, -0.9, -0.9], [0.9, 0.9, 0.9]]})
    assert env_info(boxed)["room"] == ((-0.9, -0.9, -0.9), (0.9, 0.9, 0.9))
    with pytest.raises(StudyError, match="reference.box"):
        scene.with_updates({"reference.box": [[0, 0, 0], [0, 1, 1]]})


def test_a_closed_cube_with_flipped_normals_is_a_room():
    """A Mitsuba ``cube`` with ``flip_normals`` faces inwards: its inside is free space, placement and the
    suggested placement accept it (Mitsuba's flag, not the triangles' winding, says which side is free)."""
    from study.scene.autoplace import suggest_placement as suggest

    env = {
        "type": "mitsuba",
        "scene": {
            "type": "scene",
            "lamp": {"type": "point", "position": [0, 0.8, 0]},
            "room": {"type": "cube", "flip_normals": True, "bsdf": {"type": "diffuse"}},
        },
    }
    d = {"environment": env}
    for k, v in suggest(env).items():
        a, b = k.split(".")
        d.setdefault(a, {})[b] = v
    scene = scene_from_dict(d)
    assert np.allclose(scene.bounds()[0], -1) and np.allclose(scene.bounds()[1], 1)
    with pytest.raises(StudyError, match="inside geometry"):  # the same cube, not flipped
        scene_from_dict(
            {
                **d,
                "environment": {
                    **env,
                    "scene": {**env["scene"], "room": {"type": "cube", "bsdf": {"type": "diffuse"}}},
                },
            }
        )
