"""Extension by one file, for environments: a source type registered in a throwaway module outside the package
(``study --plugin``) is validated, keyed, built and measured end to end with no file of study edited.

The plug-in ("walls") builds the box room's own triangles and textures from a ``[environment]`` table of its own
(``lo``, ``hi``), so its sweep rows must equal the built-in box room's rows of the same room (no columns): an
independent check that every layer took the environment from the source, not from the box room's code path."""

import os
import re
import sys
import textwrap

import pytest
from typer.testing import CliRunner

from study import methods
from study.cli import app
from study.errors import StudyError
from study.scene import scene_from_dict
from study.scene.sources import SOURCES
from study.tables import read_csv
from tests.conftest import scene_toml, small_scene_dict

PLUGIN = textwrap.dedent('''
    """A throwaway environment source: an axis-aligned room given by two corners, as the box room draws it."""
    from types import SimpleNamespace
    from typing import ClassVar, Literal

    import numpy as np

    from study.scene.parts import Part
    from study.scene.room import SURFACES, room_mesh, texture
    from study.scene.schema import Room
    from study.scene.sources import EnvGeometry, Source, register_source


    @register_source
    class Walls(Source):
        type: Literal["walls"]
        lo: tuple[float, float, float]
        hi: tuple[float, float, float]
        placed: ClassVar[bool] = False

        def build(self, scene):
            room = SimpleNamespace(room=Room(min=self.lo, max=self.hi), columns=())
            parts = tuple(Part(n, albedo=texture(n)) for n in SURFACES)
            return EnvGeometry(room_mesh(room), parts, kind="walls")
''')


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    (tmp_path / "walls_source.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv(methods.PLUGIN_ENV, raising=False)
    yield "walls_source"
    SOURCES.pop("walls", None)
    sys.modules.pop("walls_source", None)
    os.environ.pop(methods.PLUGIN_ENV, None)


def test_unknown_source_type_names_the_registered_ones():
    with pytest.raises(
        StudyError, match=r"environment\.type: unknown environment type 'walls'; allowed: box, mesh"
    ):
        scene_from_dict({**small_scene_dict(), "environment": {"type": "walls"}})


@pytest.mark.slow
def test_plugin_source_runs_end_to_end_like_the_box_it_draws(tmp_path, plugin):
    base = small_scene_dict()
    base["render"]["cube_res"] = 16
    walls = {**base, "environment": {"type": "walls", "lo": base["room"]["min"], "hi": base["room"]["max"]}}
    for name, scene in (("box", base), ("walls", walls)):
        (tmp_path / f"{name}.toml").write_text(scene_toml(scene))
        (tmp_path / f"sweep-{name}.toml").write_text(
            f'scene = "{name}.toml"\nmethods = ["classical", "localized", "proxy_box"]\n\n'
            '[axes]\n"object.center" = [[0.6, 1.2, 0.3]]\n'
        )
    run = CliRunner().invoke
    rows = {}
    for name in ("box", "walls"):
        out = tmp_path / "reports" / f"sweep-{name}"
        res = run(
            app,
            ["--plugin", plugin, "sweep", str(tmp_path / f"sweep-{name}.toml"), "--out", str(out)]
            + ["--cache", str(tmp_path / "cache")],
        )
        assert res.exit_code == 0, res.output
        rows[name] = {r["method"]: r for r in read_csv(out / "results.csv")}
        stages = re.findall(rf"\] sweep sweep-{name} 1/1 \S+: (\w+) \d+\.\d s\n", res.stderr)  # progress
        assert stages == ["load", "capture", "probes", "references", "methods", "metrics"], res.stderr
    assert set(rows["walls"]) >= {"classical", "localized", "proxy_box", "oracle_map"}
    for m, r in rows["box"].items():
        for col in ("angle_median_deg", "wrong_fraction", "rmse_oracle", "rmse_mitsuba"):
            if col in r:
                assert rows["walls"][m][col] == pytest.approx(r[col], rel=1e-6, abs=1e-9), (m, col)
    assert rows["walls"]["localized"]["angle_median_deg"] < rows["walls"]["classical"]["angle_median_deg"]
