"""Plug-ins that go wrong: a method whose search answers nonsense (NaN or inf points, wrong shapes, a scalar, None,
a float mask), exits or raises while tracing, a module that cannot be imported (syntax error, exception at import)
or registers a reserved or taken name. Each is one line naming the method or the module, exit code 2, no
traceback, earlier outputs untouched; a zero lookup vector is "no hit", not an error."""

import os
import sys
import textwrap

import numpy as np
import pytest
from conftest import assert_one_line_error, digest, run_cli, scene_toml, small_scene_dict

from study import backend as backends
from study import methods
from study.impostor import analytic
from study.impostor.envmap import EnvMap

HEAD = """
import numpy as np
from study.methods import Localization, Method, register
"""

METHOD = """
@register
class Bad(Method):
    name = "{name}"

    def localize(self, B, env, x, R):
{body}

    def lookups_per_ray(self):
        return 1
"""

#: (id, body of localize, words of the one-line error)
BAD_ANSWERS = [
    (
        "nan-point",
        'return Localization(l=R * float("nan"), valid=B.isfinite(B.length(R)))',
        "non-finite point",
    ),
    (
        "inf-point",
        'return Localization(l=R * float("inf"), valid=B.isfinite(B.length(R)))',
        "non-finite point",
    ),
    (
        "wrong-shape",
        "return Localization(l=B.vec(np.ones((5, 3))), valid=B.isfinite(B.length(R)))",
        "returned l with 5 values for",
    ),
    ("scalar-mask", "return Localization(l=R, valid=True)", "returned valid = a bool, not an array"),
    ("scalar-point", "return Localization(l=1.0, valid=B.isfinite(R.x))", "returned l = a float, not a V3"),
    ("none", "return None", "returned None, not a Localization"),
    ("float-mask", "return Localization(l=R, valid=B.length(R))", "returned valid as float values, not bool"),
    ("exit-0", "import sys; sys.exit(0)", "called sys.exit(0) while tracing"),
    ("raises", 'raise KeyError("oops")', "failed: KeyError"),
]


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """A small scene, a cache shared by the cases (renders once) and a plug-in directory on sys.path."""
    root = tmp_path_factory.mktemp("plugins")
    scene = small_scene_dict()
    scene["render"]["cube_res"] = 16
    scene["camera"].update(width=24, height=24)
    (root / "scene.toml").write_text(scene_toml(scene))
    sys.path.insert(0, str(root))
    yield root
    sys.path.remove(str(root))


@pytest.fixture
def plugin(setup, tmp_path, request):
    """plugin(module, source) writes a module; registry, environment and modules are restored afterwards."""
    before, made = dict(methods.REGISTRY), []

    def write(module: str, source: str) -> str:
        (setup / f"{module}.py").write_text(source)
        made.append(module)
        return module

    yield write
    methods.REGISTRY.clear()
    methods.REGISTRY.update(before)
    os.environ.pop(methods.PLUGIN_ENV, None)
    for m in made:
        sys.modules.pop(m, None)


def _workdir(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "table.csv").write_text("label\nold\n")
    return out


def _run(setup, out, module, name):
    return run_cli(
        *["--plugin", module, "run", str(setup / "scene.toml"), "-m", name, "--out", str(out)]
        + ["--cache", str(setup / "cache")],
    )


@pytest.mark.parametrize("case_id, body, words", BAD_ANSWERS, ids=[c[0] for c in BAD_ANSWERS])
def test_a_bad_answer_of_a_plugin_method_is_one_line(setup, plugin, tmp_path, case_id, body, words):
    name = "bad_" + case_id.replace("-", "_")
    module = plugin(f"plug_{name}", HEAD + METHOD.format(name=name, body=textwrap.indent(body, " " * 8)))
    out = _workdir(tmp_path)
    before = digest(out)
    res = _run(setup, out, module, name)
    assert_one_line_error(res, f"method {name!r}", before, out)
    assert words in res.output, res.output


#: (id, module source, words of the one-line error naming the module)
BAD_MODULES = [
    ("syntax-error", "def broken(:\n    pass\n", "syntax error in the plugin module"),
    (
        "raises-at-import",
        'raise RuntimeError("no licence")\n',
        "raised RuntimeError while imported: no licence",
    ),
    ("exits-at-import", "import sys\nsys.exit(0)\n", "called sys.exit(0) while imported"),
    (
        "reserved-name",
        HEAD + METHOD.format(name="oracle_map", body="        pass"),
        "label of a reference row",
    ),
    (
        "reserved-mitsuba",
        HEAD + METHOD.format(name="mitsuba", body="        pass"),
        "label of a reference row",
    ),
    ("taken-name", HEAD + METHOD.format(name="classical", body="        pass"), "'classical' is already"),
]


@pytest.mark.parametrize("case_id, source, words", BAD_MODULES, ids=[c[0] for c in BAD_MODULES])
def test_a_broken_plugin_module_is_one_line_naming_it(setup, plugin, tmp_path, case_id, source, words):
    module = plugin("plug_mod_" + case_id.replace("-", "_"), source)
    out = _workdir(tmp_path)
    before = digest(out)
    res = run_cli("--plugin", module, "methods")
    assert_one_line_error(res, f"{module}: ", before, out)
    assert words in res.output, res.output
    assert methods.REGISTRY["classical"].__module__ == "study.methods.classical"


def test_a_zero_lookup_vector_is_no_hit():
    """l = 0 points nowhere: the ray has no hit (NaN shown point), not an error and not a valid answer."""

    class Zero(methods.Method):
        name = "zero_probe"

        def localize(self, B, env, x, R):
            return methods.Localization(l=R * 0.0, valid=B.isfinite(B.length(R)))

        def lookups_per_ray(self):
            return 1

    B = backends.get("numpy")
    x, d = analytic.random_rays(50, extent=0.5, seed=1)
    env = EnvMap(analytic.box_impostor(8, [-2, -1.5, -2], [2, 1.5, 2]), B)
    with np.errstate(invalid="ignore"):
        tr = Zero().trace(B, env, B.vec(x), B.vec(d))
    assert not B.numpy(tr.valid).any() and np.isnan(B.to_numpy(tr.shown)).all()
    np.testing.assert_array_equal(B.numpy(tr.lookups), 1.0)  # its declared cost, on every ray
