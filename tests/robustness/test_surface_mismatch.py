"""Methods and the surface they model (issue 44, item 4): mirror methods model smooth mirrors and glass, glossy ones
rough conductors. The default set follows the object's surface; a chosen method that does not fit is refused in one
line naming it, or scored with allow_mismatch and its rows marked."""

import pytest
from conftest import run_cli, scene_toml, small_scene_dict

from study import methods as registry
from study.api import evaluate, load_scene
from study.errors import StudyError
from study.harness.config import surface_methods

ROUGH = {**small_scene_dict()["object"], "alpha": 0.1}


def scene(rough: bool):
    return load_scene(small_scene_dict(object=ROUGH) if rough else small_scene_dict())


@pytest.mark.parametrize(
    "rough, methods, named", [(True, ["classical"], "classical"), (False, ["prefiltered"], "prefiltered")]
)
def test_a_chosen_method_for_another_surface_is_refused_naming_it(rough, methods, named):
    with pytest.raises(StudyError) as e:
        evaluate(scene(rough), methods=methods, cache=None)
    msg = str(e.value)
    assert msg.startswith("methods:") and named in msg and "--allow-mismatch" in msg and "\n" not in msg, msg


def test_the_default_set_is_the_family_of_the_surface():
    mirror = registry.all_methods()
    ms, wrong = surface_methods(scene(True), mirror, chosen=False, allow_mismatch=False)
    assert ms and all(m.glossy for m in ms) and not wrong
    ms, wrong = surface_methods(scene(False), mirror, chosen=False, allow_mismatch=False)
    assert ms == mirror and not wrong


def test_allowed_mismatches_are_scored_and_marked(tmp_path):
    res = evaluate(scene(True), methods=["classical", "prefiltered"], cache=None, allow_mismatch=True)
    marked = dict(zip(res.table["label"], res.table["surface_mismatch"]))
    assert marked["classical"] == 1.0 and marked["prefiltered"] != 1.0


def test_the_cli_refuses_in_one_line(tmp_path):
    (tmp_path / "s.toml").write_text(scene_toml(small_scene_dict(object=ROUGH)))
    res = run_cli("run", str(tmp_path / "s.toml"), "-m", "classical", "--out", str(tmp_path / "o"))
    assert res.exit_code == 2 and "classical model smooth mirrors and glass" in " ".join(res.output.split())
    assert not (tmp_path / "o").exists()
