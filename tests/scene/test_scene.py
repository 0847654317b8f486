"""Scene validation: each invalid input gives one StudyError naming the file, the key and what is allowed."""

import pytest
from conftest import small_scene_dict

from study.errors import StudyError
from study.scene import load_scene_file, scene_from_dict


def test_shipped_scene_loads():
    s = load_scene_file("scenes/room.toml")
    assert s.render.cube_res == 256 and s.object.material.type == "conductor"


@pytest.mark.parametrize(
    "change, key, words",
    [
        (
            {"room": {"min": [-2, 0, -2], "max": [2, 3, 2], "colour": 1}},
            "room.colour",
            "unknown key; allowed: min, max",
        ),
        ({"object": {"center": [0, 1.5, 0], "radius": "big"}}, "object.radius", "number"),
        ({"object": {"center": [0, 1.5, 0], "radius": -1}}, "object.radius", "greater than 0"),
        ({"object": {"center": [0, 1.5, 0], "radius": float("nan")}}, "object.radius", "finite"),
        ({"object": {"center": [1.9, 1.5, 0], "radius": 0.4}}, "object.center", "inside the room"),
        (
            {"columns": [{"center": [0.6, 0.3], "footprint": [0.6, 0.6], "height": 2.0}]},
            "object.center",
            "overlaps columns[0]",
        ),
        (
            {
                "columns": [{"center": [0.0, 0.0], "footprint": [0.5, 0.5], "height": 2.0}],
                "object": {"center": [1.0, 1.5, 1.0], "radius": 0.3},
            },
            "reference.point",
            "inside columns[0]",
        ),
        (
            {"object": {"center": [0, 1.5, 0], "radius": 0.4, "material": {"type": "glass"}}},
            "object.material",
            "conductor",
        ),
        ({"render": {"cube_res": 0}}, "render.cube_res", "greater than or equal to 4"),
        ({"render": {"fresnel": "schlick"}}, "render.fresnel", "'exact' or 'approx'"),
        ({"camera": {"eye": [0, 1, -1], "target": [0, 2, -1], "up": [0, 1, 0]}}, "camera.up", "parallel"),
    ],
)
def test_invalid_scene(change, key, words):
    with pytest.raises(StudyError) as e:
        scene_from_dict(small_scene_dict(**change), source="bad.toml")
    msg = str(e.value)
    assert msg.startswith(f"bad.toml: {key}: "), msg
    assert words in msg, msg
    assert "\n" not in msg


def test_missing_and_broken_files(tmp_path):
    with pytest.raises(StudyError, match="nope.toml: scene file not found"):
        load_scene_file(tmp_path / "nope.toml")
    p = tmp_path / "broken.toml"
    p.write_text("[room\n")
    with pytest.raises(StudyError, match="broken.toml: not valid TOML"):
        load_scene_file(p)


def test_with_updates_revalidates_and_rejects_unknown_keys():
    s = scene_from_dict(small_scene_dict())
    assert s.with_updates({"object.center": [0.0, 1.5, 0.0]}).object.center == (0.0, 1.5, 0.0)
    with pytest.raises(StudyError, match="cfg.toml: object.centre: unknown scene key"):
        s.with_updates({"object.centre": [0, 1, 0]}, source="cfg.toml")
    with pytest.raises(StudyError, match="object.center: the sphere"):
        s.with_updates({"object.center": [5, 1, 0]})


def test_room_mesh_is_closed_and_inward():
    """The room's triangles enclose the reference point: every ray from it hits (tested in test_reference),
    and the room's face normals point inwards (towards the centre)."""
    import numpy as np

    s = scene_from_dict(small_scene_dict())
    m = s.mesh()
    tri = m.vertices[m.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = (np.array(s.room.min) + np.array(s.room.max)) / 2
    assert np.all(np.sum(n * (centre - tri[:, 0]), axis=1) > 0)
    assert len(m.surfaces) == 7 and set(np.unique(m.surface)) == set(range(6))


def test_column_faces_point_outwards():
    import numpy as np

    s = scene_from_dict(
        small_scene_dict(columns=[{"center": [1.0, -1.0], "footprint": [0.4, 0.4], "height": 1.0}])
    )
    m = s.mesh()
    f = m.faces[m.surface == m.surfaces.index("column")]
    tri = m.vertices[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = np.array([1.0, 0.5, -1.0])
    assert len(f) == 10 and np.all(np.sum(n * (tri[:, 0] - centre), axis=1) > 0)
