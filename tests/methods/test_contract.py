"""The methods' contract (study.methods.base): stateless — the same method objects evaluated twice and in another
order give identical tables and budget estimates; the lookups a ray spends never exceed the bound
``lookups_per_ray(res)``; the views come typed (:class:`study.impostor.views.Captured`), also to a plug-in, and a
view that was not captured is one line naming it."""

import math

import numpy as np
import pytest
from conftest import run_cli, small_scene_dict

from study import backend as backends
from study import methods
from study.cache import Cache
from study.errors import StudyError
from study.harness import budget
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured, ProbeSpec, Views
from study.measure.case import run_case
from study.scene import scene_from_dict

COLUMN = {"center": [-0.8, 0.3], "footprint": [0.5, 0.5], "height": 2.0}


class ViewProbe(methods.Method):
    """A method from outside the package that asks for two layers and the camera's buffer, and records what it
    is given (classical environment mapping otherwise)."""

    name = "view_probe"
    seen: list = []

    def views_needed(self):
        return Views(layers=2, screen=True)

    def localize(self, B, env, x, R):
        self.seen.append(env)
        return methods.Localization(l=R * 1.0, valid=B.isfinite(B.length(R)))

    def lookups_per_ray(self):
        return 1


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        (isinstance(v, float) and math.isnan(v) and isinstance(b[k], float) and math.isnan(b[k])) or v == b[k]
        for k, v in a.items()
    )


def test_same_methods_twice_and_in_another_order_give_identical_tables_and_budgets(tmp_path):
    d = small_scene_dict(columns=[COLUMN])
    d["render"]["cube_res"] = 16
    d["camera"].update(width=24, height=24)
    scene = scene_from_dict(d)
    ms = [
        methods.make("ssr"),
        methods.make("multi_probe", grid=[1, 1, 1]),
        methods.make("layered", layers=2),
        methods.make("linear_secant"),
        methods.make("localized"),
        ViewProbe(),
    ]
    est = budget.estimate(scene, ms)
    cache = Cache(tmp_path)
    tables = []
    for order in (ms, ms, ms[::-1]):
        rows = run_case(scene, order, cache=cache, keep_images=False).rows
        tables.append({r["label"]: {k: v for k, v in r.items() if k != "seconds"} for r in rows})
        again = budget.estimate(scene, ms)
        assert (again.bytes, again.seconds, again.time, again.memory) == (
            est.bytes,
            est.seconds,
            est.time,
            est.memory,
        )
    assert tables[0].keys() == tables[1].keys() == tables[2].keys()
    for label in tables[0]:
        assert _same(tables[0][label], tables[1][label]) and _same(tables[0][label], tables[2][label]), label
    for row in tables[0].values():  # measured means, never over the bound
        assert row["lookups_per_ray"] <= row["lookups_bound"], row["label"]
    assert (
        tables[0]["ssr(max_steps=512)"]["lookups_per_ray"] < tables[0]["ssr(max_steps=512)"]["lookups_bound"]
    )
    # the plug-in got its views typed: a Captured with two layers, the camera's buffer and the scene's knowledge
    env = ViewProbe.seen[-1]
    assert isinstance(env, Captured) and len(env.layers) >= 2 and env.screen is not None
    assert all(isinstance(layer, EnvMap) for layer in env.layers) and env.room is not None
    np.testing.assert_allclose(env.origin(), scene.reference.point)


@pytest.mark.parametrize("res", [8, 16, 32])
def test_measured_lookups_never_exceed_the_bound(res, B):
    """Every registered method on a bare box impostor (its fallbacks: the impostor as the only layer and probe, no
    screen): per ray, Trace.lookups ≤ lookups_per_ray(res); the bound needs no call before it (no state)."""
    tex = analytic.box_impostor(res, [-2, -1.5, -2], [2, 1.5, 2])
    x, d = analytic.random_rays(300, extent=1.0, seed=res)
    for m in methods.all_methods():
        bound = m.lookups_per_ray(res)
        with np.errstate(all="ignore"):
            tr = m.trace(B, EnvMap(tex, B), B.vec(x), B.vec(d))
        spent = B.numpy(tr.lookups)
        assert spent.shape == (300,) and spent.min() >= 1 and spent.max() <= bound, m.name
        assert m.lookups_per_ray(res) == bound  # unchanged by the trace


def test_a_view_that_was_not_captured_is_one_line_naming_it():
    """A caller that captures views (fallback off) and lacks what a method asks for: a StudyError naming the view."""
    B = backends.get("numpy")
    env = Captured(impostor=EnvMap(analytic.box_impostor(8, [-2, -1.5, -2], [2, 1.5, 2]), B))
    x, d = analytic.random_rays(10, extent=0.5, seed=0)
    for m, words in (
        (methods.make("layered", layers=3), "needs 3 depth layers"),
        (methods.make("ssr"), "the camera's screen buffer (Captured.screen)"),
        (methods.make("multi_probe"), f"the probe set {ProbeSpec()}"),
    ):
        with pytest.raises(StudyError, match="which its caller did not capture") as err:
            m.trace(B, env, B.vec(x), B.vec(d))
        assert words in str(err.value) and m.name in str(err.value) and "\n" not in str(err.value)
    with np.errstate(all="ignore"):
        tr = methods.make("layered", layers=1).trace(B, env, B.vec(x), B.vec(d))  # the impostor is layer 0
    assert B.numpy(tr.valid).all()


def test_every_parameter_is_described_and_study_methods_prints_it():
    """Params fields carry Field(description=...); ``study methods`` prints each one under its method."""

    for name in methods.names():
        for key, f in methods.REGISTRY[name].Params.model_fields.items():
            assert f.description, f"{name}.{key} has no description"
    res = run_cli("methods")
    assert res.exit_code == 0, res.output
    assert "  iterations: false-position steps (the listing's NITER)" in res.output
    assert "  fallback: method for the rays without a screen hit" in res.output
