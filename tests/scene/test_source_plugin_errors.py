"""Environment-source plug-ins that go wrong, held to the method plug-ins' standard
(tests/methods/test_plugin_errors.py):
a ``build()`` that raises, exits, returns no geometry, triangles without faces, vertex indices out of range, NaN
vertices or surface ids past its parts is one line naming the plug-in, exit code 2, no traceback, earlier outputs
untouched. And the plug-in's code is in the cache keys (as the methods' code is): editing ``build()`` between two
runs does not reuse the renders of the old one."""

import os
import sys
import textwrap

import pytest
from conftest import assert_one_line_error, digest, run_cli, scene_toml, small_scene_dict

from study import methods
from study.scene.sources import SOURCES

PLUGIN = '''
"""A throwaway environment source: the box room's triangles, then {what}."""
from types import SimpleNamespace
from typing import ClassVar, Literal

import numpy as np

from study.scene.parts import Part
from study.scene.room import SURFACES, RoomMesh, room_mesh, texture
from study.scene.schema import Room
from study.scene.sources import EnvGeometry, Source, register_source


@register_source
class Walls(Source):
    type: Literal["walls"]
    placed: ClassVar[bool] = False

    def build(self, scene):
        room = SimpleNamespace(room=Room(min=(-2.0, 0.0, -2.0), max=(2.0, 3.0, 2.0)), columns=())
        m = room_mesh(room)
        V, F, UV, S = m.vertices.copy(), m.faces.copy(), m.uv.copy(), m.surface.copy()
        parts = tuple(Part(n, albedo=texture(n, 8)) for n in SURFACES)
        colors = None
{body}
        return EnvGeometry(RoomMesh(V, F, UV, S, m.surfaces, colors), parts, kind="walls")
'''

#: (id, lines of build() before it returns, words of the one-line error)
BAD_BUILDS = [
    ("raises", 'raise KeyError("oops")', "build() failed: KeyError: 'oops'"),
    ("returns-none", "return None", "build() returned None, not an EnvGeometry"),
    ("exits-0", "import sys; sys.exit(0)", "build() called sys.exit(0)"),
    ("exits-1", "raise SystemExit(1)", "build() called sys.exit(1)"),
    ("no-faces", "F, S = F[:0], S[:0]", "built no triangles"),
    (
        "no-vertices",
        "V, F, UV, S = V[:0], F[:0], UV[:0], S[:0]",
        "built no triangles",
    ),
    ("index-past-the-end", "F[3, 1] = 999", "triangle 3 has vertex index 999; the mesh has 24 vertices"),
    ("negative-index", "F[0, 0] = -1", "triangle 0 has vertex index -1; the mesh has 24 vertices"),
    ("nan-vertex", 'V[5, 1] = float("nan")', "vertex 5 is not finite"),
    ("inf-vertex", 'V[7, 2] = float("inf")', "vertex 7 is not finite"),
    ("surface-past-the-parts", "S[4] = 9", "triangle 4 has surface id 9; there are 7 parts"),
    ("negative-surface", "S[2] = -1", "triangle 2 has surface id -1; there are 7 parts"),
    ("float-faces", "F = F.astype(float)", "faces are float64, not integers"),
    ("flat-vertices", "V = V.ravel()", "vertices have shape (72,), not (V, 3)"),
    ("short-surface-ids", "S = S[:-2]", "surface ids for 10 triangles; the mesh has 12"),
    ("nan-uv", 'UV[1, 0] = float("nan")', "uv 1 is not finite"),
    (
        "nan-colour",
        'parts = parts[:2] + (Part("wall_x-", color=(float("nan"), 0.5, 0.5)),) + parts[3:]',
        "part 2 ('wall_x-'): its colour is not finite (nan, 0.5, 0.5)",
    ),
    (
        "inf-emission",
        'parts = parts[:2] + (Part("wall_x-", color=(0.5,) * 3, emission=(1.0, float("inf"), 1.0)),) + parts[3:]',
        "part 2 ('wall_x-'): its emission is not finite (1, inf, 1)",
    ),
    (
        "nan-texture",
        'parts[3].albedo[4, 5, 1] = float("nan")',
        "part 3 ('wall_x+'): its texture is not finite (first at row 4, column 5)",
    ),
    (
        "nan-vertex-colour",
        'colors = np.full((len(V), 3), 0.5, np.float32); colors[6, 0] = float("nan")',
        "the colour of vertex 6 (part 'ceiling') is not finite (nan, 0.5, 0.5)",
    ),
    (
        "not-a-part",
        "parts = parts[:-1] + ({'name': 'column'},)",
        "part 6 is a dict, not a study.scene.parts.Part",
    ),
]


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """A small scene on the plug-in's environment, a shared cache, and the plug-in directory on sys.path."""
    root = tmp_path_factory.mktemp("source-plugins")
    scene = small_scene_dict()
    scene["render"]["cube_res"] = 16
    scene["camera"].update(width=24, height=24)
    scene["environment"] = {"type": "walls"}
    (root / "scene.toml").write_text(scene_toml(scene))
    sys.path.insert(0, str(root))
    yield root
    sys.path.remove(str(root))


@pytest.fixture
def plugin(setup, monkeypatch):
    """plugin(module, body) writes a source plug-in; the registry and the modules are restored afterwards."""
    monkeypatch.delenv(methods.PLUGIN_ENV, raising=False)
    made = []

    def write(module: str, body: str) -> str:
        (setup / f"{module}.py").write_text(
            PLUGIN.format(what=module, body=textwrap.indent(body, " " * 8) if body else "")
        )
        sys.modules.pop(module, None)
        SOURCES.pop("walls", None)
        made.append(module)
        return module

    yield write
    SOURCES.pop("walls", None)
    for m in made:
        sys.modules.pop(m, None)
    os.environ.pop(methods.PLUGIN_ENV, None)  # --plugin set it (monkeypatch would restore it on undo)


def _workdir(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "table.csv").write_text("label\nold\n")
    return out


def _run(setup, out, module, *extra):
    return run_cli(
        *["--plugin", module, "run", str(setup / "scene.toml"), "-m", "classical", "--out", str(out)]
        + ["--cache", str(setup / "cache"), *extra],
    )


@pytest.mark.parametrize("case_id, body, words", BAD_BUILDS, ids=[c[0] for c in BAD_BUILDS])
def test_a_bad_build_of_a_plugin_source_is_one_line(setup, plugin, tmp_path, case_id, body, words):
    module = plugin("walls_" + case_id.replace("-", "_"), body)
    out = _workdir(tmp_path)
    before = digest(out)
    res = _run(setup, out, module)
    assert_one_line_error(res, f"environment 'walls' (plug-in {module})", before, out)
    assert words in res.output, res.output


def test_a_good_build_of_the_same_plugin_runs(setup, plugin, tmp_path):
    """The control: the template with nothing planted runs, and writes its table."""
    module = plugin("walls_good", "")
    out = tmp_path / "out"
    res = _run(setup, out, module)
    assert res.exit_code == 0, res.output
    assert "classical" in (out / "table.csv").read_text()


def test_editing_build_between_two_runs_renders_anew(setup, plugin, tmp_path):
    """The plug-in's code is in the cache keys: after ``build()`` is edited (the room's textures darkened), the
    second run's numbers equal a fresh run's (no cache), not the first run's."""
    from study.tables import read_csv

    def rmse(out):
        return {r["label"]: r["rmse_mitsuba"] for r in read_csv(out / "table.csv")}

    module = plugin("walls_edited", "")
    first = tmp_path / "first"
    assert _run(setup, first, module).exit_code == 0
    plugin(module, "parts = tuple(Part(p.name, albedo=p.albedo * 0.3) for p in parts)")
    second, fresh = tmp_path / "second", tmp_path / "fresh"
    res = _run(setup, second, module)
    assert res.exit_code == 0, res.output
    sys.modules.pop(module, None)
    SOURCES.pop("walls", None)
    res = run_cli(
        *["--plugin", module, "run", str(setup / "scene.toml"), "-m", "classical", "--out", str(fresh)]
        + ["--cache", str(tmp_path / "fresh-cache")],
    )
    assert res.exit_code == 0, res.output
    assert rmse(second) == pytest.approx(rmse(fresh), rel=1e-6, nan_ok=True)
    assert rmse(second)["classical"] != pytest.approx(rmse(first)["classical"], rel=1e-3)


def test_the_plugin_code_is_in_every_content_key_of_its_scene(setup, plugin):
    """The environment's key (impostors, renders, the memo) and the scene's (sweep cases, truth) change when the
    plug-in's file does; study's own sources keep the keys they had (no code field: old caches stay valid)."""
    from study.methods import load_plugins
    from study.scene import scene_from_dict
    from study.scene.environment import env_key
    from study.scene.schema import load_scene_file
    from study.scene.sources import key_fields

    module = plugin("walls_keyed", "")
    load_plugins([module])
    scene = load_scene_file(setup / "scene.toml")
    keys = env_key(scene), key_fields(scene)
    assert "plugin_code" in keys[1]["environment"]
    (setup / f"{module}.py").write_text((setup / f"{module}.py").read_text() + "\n# edited\n")
    assert env_key(scene) != keys[0] and key_fields(scene) != keys[1]
    box = scene_from_dict(small_scene_dict())
    assert "plugin_code" not in key_fields(box)["environment"] and "plugin_code" not in env_key(box)
