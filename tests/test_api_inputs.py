"""Wrong arguments to the Python API and the sweep schema are one StudyError line naming the argument or key,
never a bare TypeError or a message about an internal union branch."""

import pytest
from conftest import error_output, run_cli

import study
from study.errors import StudyError
from study.harness.sweep import SweepConfig
from study.validation import validate


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"cache": 123}, "cache: cache is a directory path or None, not int"),
        ({"overrides": [1, 2]}, "overrides: overrides is a dict of dotted scene keys → values, not list"),
    ],
)
def test_evaluate_refuses_wrong_argument_types(kwargs, words):
    with pytest.raises(StudyError, match=words):
        study.evaluate("scenes/room.toml", ["classical"], **kwargs)


@pytest.mark.parametrize(
    "call",
    [
        lambda: study.load_scene("scenes/room.toml", {"object.center": {0.5, 1.2, 0.3}}),
        lambda: study.load_scene({"object": {"center": {0.5, 1.0, 0.3}}}, {"camera.width": 32}),
    ],
    ids=["override", "scene-dict"],
)
def test_a_set_is_not_a_point(call):
    with pytest.raises(StudyError, match="object.center: .*a set has no order"):
        call()


def test_methods_reachable_right_after_import_study():
    """The README's plug-in example: `import study` then `@study.methods.register`."""
    assert callable(study.methods.register) and "classical" in study.methods.REGISTRY


@pytest.mark.parametrize(
    "axes, words",
    [
        ({"object.center": {"line": {"from": [0, 1, 0], "to": [1, 1, 1], "steps": 0}}},
         "axes.object.center.line.steps: Input should be greater than or equal to 1"),
        ({"render.cube_res": 16}, "axes.render.cube_res: Input should be a valid list"),
    ],
)  # fmt: skip
def test_sweep_axis_errors_name_the_axis_key(axes, words):
    with pytest.raises(StudyError, match=words):
        validate(SweepConfig, {"scene": "x.toml", "axes": axes}, file="s.toml")


def test_run_refusal_names_the_scene_file(tmp_path):
    res = run_cli(
        *[
            "run",
            "scenes/room.toml",
            "-m",
            "classical",
            "--set",
            "render.spp=2000000000",
            "--out",
            str(tmp_path),
        ],
    )
    text = error_output(res)  # progress lines (stderr) may precede the one error line
    assert res.exit_code == 2 and text.startswith("error: scenes/room.toml: render.spp"), text
    assert "evaluate" not in text
