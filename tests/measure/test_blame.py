"""Messages name the element that is wrong: a NaN colour in a mesh file's material was reported as "lower
light.intensity (now 6)" (the renders came out NaN and every non-finite render blamed the light); now the
environment is refused when built, naming the vertex and part whose colour is not finite, and a non-finite
render blames the light only where it is strong enough to overflow float32."""

import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import error_output, run_cli

from study.errors import StudyError
from study.measure import inputs
from study.scene import scene_from_dict
from tests.conftest import small_scene_dict
from tests.robustness.test_bad_inputs import digest

ASSETS = Path(__file__).parents[1] / "assets"


def test_a_nan_colour_in_a_file_names_the_part_not_the_light(tmp_path):
    for f in ("neg_room.obj", "wall.png"):
        shutil.copy(ASSETS / f, tmp_path / f)
    mtl = (ASSETS / "neg_room.mtl").read_text()
    assert "Kd 0.63 0.63 0.63" in mtl
    (tmp_path / "neg_room.mtl").write_text(mtl.replace("Kd 0.63 0.63 0.63", "Kd nan 0.63 0.63"))
    out = tmp_path / "out"
    out.mkdir()
    (out / "table.csv").write_text("label\nold\n")
    before = digest(out)
    res = run_cli(
        *["run", str(tmp_path / "neg_room.obj"), "-m", "classical", "--out", str(out)]
        + ["--cache", str(tmp_path / "cache")],
    )
    text = error_output(res)
    assert res.exit_code == 2, res.output
    assert text.startswith("error: ") and "\n" not in text, text
    assert "light.intensity" not in text, text
    assert "neg_room.mtl line 2: Kd: 'nan 0.63 0.63'" in text, text  # the file, its line and its statement
    assert digest(out) == before


def test_a_non_finite_render_blames_the_light_only_where_it_can_overflow():
    img = np.ones((4, 4, 3), np.float32)
    img[1, 2, 0] = np.nan
    weak = scene_from_dict(small_scene_dict())
    with pytest.raises(StudyError) as err:
        inputs.finite(weak, "camera render", img)
    assert err.value.key == "environment" and "1 pixel(s) NaN or inf" in str(err.value)
    assert "intensity 7, which cannot overflow" in str(err.value) and "box room" in str(err.value)
    strong = weak.with_updates({"light.intensity": [1e39, 1e39, 1e39]})
    with pytest.raises(StudyError, match=r"light.intensity: .*lower light.intensity \(now 1e\+39\)"):
        inputs.finite(strong, "camera render", img)
    inputs.finite(weak, "camera render", np.ones((4, 4, 3), np.float32))  # finite: no error
