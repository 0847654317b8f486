"""A file's camera used with its orientation and field of view as the file says (issue 54, item 2), where its axis
is blocked right in front of the eye (VC.glb's chase camera: its vehicle fills the middle of the frame, and the
view used to be re-aimed at a sphere placed elsewhere, 104° away from the file's aim): the scene's camera keeps the
node's forward, up (its roll) and yfov, and the sphere lies whole inside that frame, in free space, seen unblocked
from the eye and the reference point. Checked against the glTF written here: its rotation, its boxes."""

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import camera_gltf
from scipy.spatial.transform import Rotation

import study
from study.scene import placement

CORPUS = Path(__file__).resolve().parents[1] / "assets" / "corpus"
EYE = np.array([1.0, 1.6, 3.0])
ROT = Rotation.from_euler("YXZ", [30, -20, 35], degrees=True)  # yaw left, pitch down, a strong roll
YFOV = 0.9  # radians
FORWARD, UP = ROT.apply([0.0, 0.0, -1.0]), ROT.apply([0.0, 1.0, 0.0])
BLOCK = EYE + 0.6 * FORWARD  # the middle of a 0.4 m box on the axis, 0.6 m ahead (the chase camera's vehicle)
BOXES = [
    (BLOCK - 0.2, BLOCK + 0.2),
    (np.array([-4.0, 0.0, -4.0]), np.array([-2.0, 3.0, -2.0])),  # buildings
    (np.array([1.5, 0.0, -4.5]), np.array([3.5, 2.0, -2.5])),
]


def _box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """The 8 corners and 12 triangles (counter-clockwise seen from outside) of the box lo..hi."""
    V = np.array([[(hi if i & k else lo)[a] for a, k in enumerate((1, 2, 4))] for i in range(8)], np.float32)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    F = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], np.uint16)
    return V, F


def _write(path: Path, aspect: float = 1.0) -> None:
    """A 12 m ground quad facing up, :data:`BOXES` and a perspective camera node at :data:`EYE` rotated by
    :data:`ROT`, yfov :data:`YFOV`, ``aspect`` (width / height); one buffer, a data URI."""
    parts = [
        (
            np.array([[-6, 0, -6], [6, 0, -6], [6, 0, 6], [-6, 0, 6]], np.float32),
            np.array([[0, 2, 1], [0, 3, 2]]),
        )
    ]
    parts += [_box(lo, hi) for lo, hi in BOXES]
    V, F, n = [], [], 0
    for v, f in parts:
        V.append(v)
        F.append(np.asarray(f) + n)
        n += len(v)
    V, F = np.concatenate(V).astype(np.float32), np.concatenate(F).astype(np.uint16)
    camera_gltf(path, V, F, EYE, ROT.as_quat(), YFOV, aspect)


def _pixels(centre, radius: float, tan_half: float, aspect: float = 1.0) -> np.ndarray:
    """Image-plane coordinates (x, y in units of the frame's half-width and half-height; ``aspect`` = height /
    width, ``tan_half`` horizontal) of 4000 points on the sphere's surface, as the file's camera (its rotation
    :data:`ROT`, looking down its −z) projects them."""
    i = np.arange(4000) + 0.5
    z = 1 - 2 * i / len(i)
    phi = np.pi * (1 + 5**0.5) * i
    s = np.sqrt(1 - z * z)
    pts = np.asarray(centre) + radius * np.stack([s * np.cos(phi), z, s * np.sin(phi)], -1)
    local = ROT.inv().apply(pts - EYE)
    assert np.all(local[:, 2] < 0), "part of the sphere is behind the camera"
    return local[:, :2] / (-local[:, 2:] * tan_half) / [1.0, aspect]


@pytest.mark.parametrize("size", [{}, {"camera.width": 64, "camera.height": 32}], ids=["square", "2:1"])
def test_a_file_camera_keeps_its_aim_roll_and_fov_and_sees_the_sphere_whole(tmp_path, size):
    """The camera's axis is blocked 0.4 m ahead: the scene's camera still looks along the node's −z with its +y
    up and the file's field of view, and the sphere (off the axis) projects whole inside the frame, filling a
    visible share of it, touching no box and seen unblocked (it was re-aimed at a sphere placed elsewhere)."""
    p = tmp_path / "chase.gltf"
    _write(p)
    sc = study.load_scene(str(p), size)
    cam, c, r = sc.camera, np.asarray(sc.object.center), sc.object.radius
    got = np.subtract(cam.target, cam.eye)
    np.testing.assert_allclose(cam.eye, EYE, atol=1e-6)
    np.testing.assert_allclose(got / np.linalg.norm(got), FORWARD, atol=1e-6, err_msg=sc.placement_line())
    right = np.cross(FORWARD, cam.up)
    np.testing.assert_allclose(np.cross(right / np.linalg.norm(right), FORWARD), UP, atol=1e-6)  # its roll
    assert cam.fov == pytest.approx(math.degrees(YFOV))  # aspect 1: horizontal = vertical = yfov
    xy = _pixels(c, r, math.tan(YFOV / 2), cam.height / cam.width)
    assert np.abs(xy).max() < 1.0, (np.abs(xy).max(), sc.placement_line())  # whole inside the frame
    assert xy.max(0)[0] - xy.min(0)[0] > 0.1  # not a speck: a twentieth of the frame's width or more
    for lo, hi in BOXES:
        assert np.linalg.norm(np.maximum(np.maximum(lo - c, 0), c - hi)) > r  # touches no box
    assert c[1] > r  # above the ground
    mesh = sc.mesh()
    assert placement.sees(mesh, cam.eye, c, r) == 1.0
    assert placement.sees(mesh, sc.reference.point, c, r) == 1.0
    assert "re-aimed" not in sc.placement_line()


def test_a_user_set_object_centre_still_wins(tmp_path):
    """object.center given: the sphere stays there and the camera keeps the file's aim."""
    p = tmp_path / "chase.gltf"
    _write(p)
    centre = [0.0, 0.6, 0.0]
    sc = study.load_scene(str(p), {"object.center": centre, "object.radius": 0.3})
    assert sc.object.center == tuple(centre)
    got = np.subtract(sc.camera.target, sc.camera.eye)
    np.testing.assert_allclose(got / np.linalg.norm(got), FORWARD, atol=1e-6)


def test_a_file_camera_with_no_free_spot_in_view_is_re_aimed_and_says_so():
    """Mitsuba's projector test scene: a camera 1 unit above a 2 km plane with a 170° field of view; no sphere of a
    tenth of the radius asked for fits in its view (1 unit deep), so the camera is re-aimed at the object, and the
    placement line says so (it was re-aimed silently)."""
    p = CORPUS / "xml/mitsuba-data/tests/scenes/projector/test_projector_constant_direct.xml"
    sc = study.load_scene(str(p), {"camera.width": 32, "camera.height": 32})
    assert "the file's camera re-aimed at the object (no free spot in its view)" in sc.placement_line()
    assert sc.camera.target == sc.object.center


@pytest.mark.parametrize(
    ("size", "want"),
    [({}, (256, 171)), ({"camera.width": 96}, (96, 64)), ({"camera.height": 100}, (150, 100))],
    ids=["default", "width given", "height given"],
)
def test_the_frame_takes_the_file_cameras_aspect_where_left_out(tmp_path, size, want):
    """A 3:2 camera (yfov 0.9): the frame the user leaves out takes its 3:2, so that both fields of view are the
    file's: horizontal 2·atan(tan(yfov/2)·1.5), vertical yfov (to the frame's rounding; it was square: vertical =
    horizontal, 35 % wider than the file's). Both sizes given: the user's, the horizontal fov the file's."""
    p = tmp_path / "wide.gltf"
    _write(p, aspect=1.5)
    cam = study.load_scene(str(p), size).camera
    assert (cam.width, cam.height) == want
    assert cam.fov == pytest.approx(math.degrees(2 * math.atan(math.tan(YFOV / 2) * 1.5)))
    vertical = 2 * math.atan(math.tan(math.radians(cam.fov) / 2) * cam.height / cam.width)
    assert vertical == pytest.approx(YFOV, rel=0.01)
    both = study.load_scene(str(p), {"camera.width": 64, "camera.height": 64}).camera
    assert (both.width, both.height) == (64, 64) and both.fov == pytest.approx(cam.fov)


def test_a_pole_in_front_of_the_sphere_hides_part_of_it():
    """A 4 cm pole 2 m in front of a 1 m sphere 5 m away, 0.3 m off the line of sight (VC.glb's first try had a
    pole across the sphere's image): not seen whole; without the pole, seen whole."""
    from types import SimpleNamespace

    from study.scene.inview import unblocked

    V, F = _box(np.array([0.3, -3.0, 2.96]), np.array([0.34, 3.0, 3.0]))
    pole = SimpleNamespace(vertices=V, faces=F.astype(np.int32))
    far = SimpleNamespace(vertices=V + [50.0, 0, 0], faces=F.astype(np.int32))
    assert not unblocked(pole, (0, 0, 0), (0, 0, 5), 1.0)
    assert unblocked(far, (0, 0, 0), (0, 0, 5), 1.0)
