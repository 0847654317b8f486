"""Light and view that show the scene (issue 54, item 2), each against what the file says or what geometry says:
a flat file's light off its plane; a single object seen from outside under a sky it can reflect; a reference point
that sees the object past a shape in between (a matpreview-like Mitsuba scene); a glTF camera used with its
orientation and field of view."""

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import camera_gltf

import study
from study.scene import placement

FLAT = 0.02  # study.scene.autoplace.FLAT

CORPUS = Path(__file__).resolve().parents[1] / "assets" / "corpus"
TRIANGLE = CORPUS / "gltf" / "TriangleWithoutIndices" / "glTF" / "TriangleWithoutIndices.gltf"
BOX = CORPUS / "gltf" / "Box" / "glTF" / "Box.gltf"
SMALL = {
    "camera.width": 32,
    "camera.height": 32,
    "render.cube_res": 32,
    "render.spp": 8,
    "render.cube_spp": 4,
}

MATPREVIEW_LIKE = """<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 1.2, 6" target="0, 0.6, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/></film>
  </sensor>
  <shape type="cube" id="stand">
    <transform name="to_world"><scale value="0.6"/><translate value="0, 0.6, 0"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.3, 0.2"/></bsdf>
  </shape>
  <shape type="rectangle" id="floor">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="3"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf>
  </shape>
</scene>
"""


def test_a_flat_files_light_is_off_its_plane():
    """TriangleWithoutIndices lies in z = 0: the light used to sit at its bounds' centre, in its plane (every
    surface lit edge-on: the render black). Now it stands off the plane by half the diagonal."""
    sc = study.load_scene(str(TRIANGLE))
    lo, hi = sc.bounds()
    ext = hi - lo
    axis = int(np.argmin(ext))
    assert ext[axis] <= FLAT * np.linalg.norm(ext)
    off = abs(sc.light.position[axis] - (lo[axis] + hi[axis]) / 2)
    assert off > 0.25 * np.linalg.norm(ext), (sc.light.position, lo, hi)
    assert sc.lamp()


def test_a_flat_file_renders_lit():
    """Mitsuba's picture of the flat triangle is not black (item 3's black share under its limit)."""
    res = study.evaluate(str(TRIANGLE), ["classical"], cache=None, overrides=SMALL)
    assert res.table["black_share"].iloc[0] < 0.5, res.table["black_share"].iloc[0]


def test_a_single_object_seen_from_outside_gets_a_sky_the_mirror_shows(tmp_path):
    """The Khronos Box seen from outside: the studio sky, said in the placement line; the mirror sphere's pixels in
    Mitsuba's picture are not the background's colour (they were black void, as the background)."""
    sc = study.load_scene(str(BOX))
    assert sc.environment.sky == "studio" and 'sky "studio"' in sc.placement_line()
    res = study.evaluate(sc, ["classical"], cache=None)
    row = res.table.iloc[0]
    assert row["mirrored_void"] == 0.0 and row["black_share"] < 0.5
    img, mask = res.images["mitsuba"], res.mask
    assert np.mean(img[mask]) > 0.05  # the sphere shows light: sky and box
    given = study.load_scene({"environment": {"type": "mesh", "file": str(BOX), "sky": "#203040"}})
    assert given.environment.sky == "#203040" and "studio" not in given.placement_line()  # the user's kept


def test_the_reference_point_sees_the_object_past_a_shape_in_between(tmp_path):
    """A matpreview-like scene (a stand on a floor, the file's camera in front): the object goes on the camera's
    axis before the stand, and the reference point chosen beside the stand used to have the stand between it and
    the object (it saw 0 % of it); now it sees the whole sphere."""
    p = tmp_path / "matpreview_like.xml"
    p.write_text(MATPREVIEW_LIKE)
    sc = study.load_scene(str(p))
    seen = placement.sees(sc.mesh(), sc.reference.point, sc.object.center, sc.object.radius)
    assert seen == 1.0, sc.placement_line()


def _camera_gltf(path: Path, eye, quat, yfov: float, aspect: float) -> None:
    """A ground quad (10 m, facing up: a flat file, as VC.glb's ground nearly is) and a perspective camera node at
    ``eye`` rotated by ``quat`` (x, y, z, w): a small glTF written here (:func:`conftest.camera_gltf`)."""
    V = np.array([[-5, 0, -5], [5, 0, -5], [5, 0, 5], [-5, 0, 5]], np.float32)
    camera_gltf(path, V, [[0, 2, 1], [0, 3, 2]], eye, quat, yfov, aspect)


def test_a_gltf_camera_is_used_with_its_orientation_and_field_of_view(tmp_path):
    """A camera 1.6 m up, turned 30° left and 20° down (VC.glb-like: the view used to be re-aimed at the sphere):
    the scene's camera looks along the node's −z, with the horizontal fov of yfov and aspectRatio, and the object
    is on that axis."""
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_euler("YX", [30, -20], degrees=True)
    eye = (1.0, 1.6, 3.0)
    p = tmp_path / "camera.gltf"
    _camera_gltf(p, eye, rot.as_quat(), yfov=0.6, aspect=1.5)
    sc = study.load_scene(str(p))
    cam = sc.camera
    want = rot.apply([0.0, 0.0, -1.0])
    got = np.subtract(cam.target, cam.eye)
    np.testing.assert_allclose(cam.eye, eye, atol=1e-6)
    np.testing.assert_allclose(got / np.linalg.norm(got), want, atol=1e-6)
    assert cam.fov == pytest.approx(math.degrees(2 * math.atan(math.tan(0.3) * 1.5)))
    to_obj = np.subtract(sc.object.center, cam.eye)
    assert np.linalg.norm(np.cross(to_obj / np.linalg.norm(to_obj), want)) < 1e-6  # on the view axis
