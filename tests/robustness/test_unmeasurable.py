"""A scene that cannot be measured is one line naming why and exit 2 from ``study run`` (issue 54, bad input):
positions that are not finite (NaN in the file), no surface of non-zero area, every ray escaping (a scene with no
surface at all; every ray the object reflects leaving the scene with no sky; a camera that sees no object), and a
key given as NaN. Nothing is written. Under a sky the escaping rays show it: that case is measured."""

from pathlib import Path

import pytest
from conftest import error_output, run_cli

SMALL = ["--set", "camera.width=16", "--set", "camera.height=16", "--set", "render.cube_res=16",
         "--set", "render.spp=2", "--set", "render.cube_spp=2"]  # fmt: skip
PLY = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
PLY += "element face 2\nproperty list uchar int vertex_indices\nend_header\n"

CASES = {
    "nan-obj": ("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n", "scene.obj", [], "is not finite"),
    "nan-ply": (PLY + "0 0 0\n1 0 0\n0 nan 0\n0 0 1\n3 0 1 2\n3 0 1 3\n", "scene.ply", [], "is not finite"),
    "zero-area-obj": (
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3\nf 2 3 4\n",
        "scene.obj",
        [],
        "non-zero area",
    ),
    "zero-area-ply": (
        PLY + "0 0 0\n1 0 0\n2 0 0\n3 0 0\n3 0 1 2\n3 1 2 3\n",
        "scene.ply",
        [],
        "non-zero area",
    ),
    "no-surface": (
        '<scene version="3.0.0"><emitter type="constant"/></scene>',
        "scene.xml",
        [],
        "no triangles",
    ),
    "no-ray-reaches-the-object": (None, "room.toml", ["--set", "camera.target=[0, 1.5, -5]"], "does not see"),
    "nan-key": (None, "room.toml", ["--set", "object.center=[nan, 1.2, 0.3]"], "finite"),
    # one triangle behind the object, which faces away from it: every ray it reflects leaves the scene, no sky
    "everything-escaping": ("", "void.toml", [], "leaves the scene and no sky shows there"),
}
VOID = """
[environment]
type = "mesh"
file = "triangle.obj"
[object]
center = [0.0, 0.0, 5.0]
radius = 0.5
[camera]
eye = [0.0, 0.0, 8.0]
target = [0.0, 0.0, 5.0]
[reference]
point = [0.0, 0.0, 6.0]
"""


@pytest.mark.parametrize("case", list(CASES))
def test_a_scene_that_cannot_be_measured_is_one_line_naming_why_and_exit_2(tmp_path, case):
    text, name, sets, words = CASES[case]
    if text is None:
        scene = Path(__file__).resolve().parents[2] / "scenes" / name
    else:
        scene = tmp_path / name
        scene.write_text(text or VOID)
        (tmp_path / "triangle.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n")
    out = tmp_path / "out"
    res = run_cli("run", scene, "-m", "classical", *SMALL, *sets, "--out", out, "--cache", tmp_path / "cache")
    text = error_output(res)  # a mesh file's load summary and placement lines may come first (stderr)
    lines = [ln for ln in text.splitlines() if not ln.startswith(("loaded ", "placement: "))]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], text
    assert "Traceback" not in res.output and not out.exists()


def test_the_same_void_under_a_sky_is_measured(tmp_path):
    """Under a sky the escaping rays show it: the case is measured (classical right on every ray), not refused."""
    (tmp_path / "void.toml").write_text(
        VOID.replace('file = "triangle.obj"', 'file = "triangle.obj"\nsky = "#8899aa"')
    )
    (tmp_path / "triangle.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n")
    out = tmp_path / "out"
    res = run_cli(
        "run", tmp_path / "void.toml", "-m", "classical", *SMALL, "--out", out, "--cache", tmp_path / "c"
    )
    assert res.exit_code == 0, res.output
    assert (out / "table.csv").is_file()
