"""The time estimate told before a command starts (study.harness.estimate) and the ETA it seeds (study.progress)."""

import io
import json

import numpy as np
from rich.console import Console

from study import methods as registry
from study import progress
from study.cache import Cache
from study.cli.progress import Lines
from study.harness import estimate
from study.impostor.capture import impostor_key, render_cube
from study.scene import scene_from_dict
from tests.conftest import small_scene_dict


def _scene(**render):
    d = small_scene_dict()
    d["render"].update(render)
    return scene_from_dict(d)


def test_units_scale_with_the_work_of_each_stage():
    ms = [registry.make("classical"), registry.make("localized", iterations=3)]
    a = estimate.units(_scene(), ms)
    b = estimate.units(_scene(cube_spp=8), ms)  # twice the capture's samples
    sc = _scene()
    texels = 6 * sc.render.cube_res**2
    depth = sc.render.max_depth / 4
    assert np.isclose(b["renders"] - a["renders"], texels * 4 * (1 + 1 / 8) * depth)
    assert b["exact"] == a["exact"] and b["traces"] == a["traces"] and b["columns"] == a["columns"]
    # columns: pixels × methods; traces: rays × the methods' lookup bounds
    one = estimate.units(sc, ms[:1])
    assert np.isclose(a["columns"], 2 * one["columns"])
    res = sc.render.cube_res
    bound = sum(m.lookup_bound(res) for m in ms)
    assert np.isclose(a["traces"], one["traces"] * bound / ms[0].lookup_bound(res))
    assert estimate.units(sc, ms, rendered=False)["renders"] == 0.0


def test_renders_are_counted_once_per_impostor_and_not_when_cached(tmp_path):
    ms = [registry.make("classical")]
    table = {**estimate.DEFAULT_RATES, "case": 0.0}
    sc = _scene()
    moved = sc.with_updates({"object.center": [0.5, 1.2, 0.3]})  # the same impostor
    one = estimate.forecast([sc], ms, table=table)
    two = estimate.forecast([sc, moved], ms, table=table)
    assert two.cases == 2 and np.isclose(two.stages["renders"], one.stages["renders"])
    assert np.isclose(two.stages["columns"], 2 * one.stages["columns"], rtol=0.2)
    # the impostor in the cache: no renders at all
    cache = Cache(tmp_path)
    r = sc.render
    cache.get("radiance", impostor_key(sc), lambda: np.zeros(6 * r.cube_res**2 * 3), code=render_cube)
    assert estimate.cached_impostor(sc, cache)
    assert estimate.forecast([sc], ms, cache=cache, table=table).stages["renders"] == 0.0
    assert estimate.forecast([sc], ms, cache=Cache(tmp_path / "other"), table=table).stages["renders"] > 0


def test_the_calibrated_table_is_read_and_the_line_names_it(tmp_path):
    path = tmp_path / "costs.json"
    path.write_text(json.dumps({"seconds_per_unit": {"columns": 1.0, "nonsense": 5}}))
    got = estimate.rates(path)
    assert (
        got["columns"] == 1.0
        and "nonsense" not in got
        and got["renders"] == estimate.DEFAULT_RATES["renders"]
    )
    est = estimate.Forecast(3, {"renders": 120.0, "columns": 30.0}, fixed=0.0, jobs=2)
    assert est.seconds == 75.0
    line = estimate.told(est, "fig4")
    assert line.startswith("estimate fig4: about 1 min 15 s for 3 cases, 2 at a time (renders 2 min 0 s")


def test_the_eta_starts_from_the_estimate_until_a_unit_has_finished():
    out = io.StringIO()
    with progress.reporting(Lines(Console(file=out, width=200), every=0)):
        with progress.task("fig", 4) as t:
            assert t.eta is None  # nothing known yet
            progress.expect(100.0, "estimate fig: about 1 min 40 s")
            assert 99.0 <= t.eta <= 100.0
            t.t0 -= 30.0  # 30 s spent
            assert 69.0 <= t.eta <= 70.0
            t.t0 -= 100.0  # past the estimate: 0 left, never negative
            assert t.eta == 0.0
            progress.advance("a")  # one case took 130 s: the measured rate from now on
            assert 389.0 <= t.eta <= 391.0
    assert "estimate fig: about 1 min 40 s" in out.getvalue()
    # without a reporter (the API, workers) nothing is told or kept
    with progress.task("quiet", 2) as t:
        progress.expect(50.0, "x")
        assert t.expected is None


def test_seeds_of_one_geometry_read_one_distance_capture_and_draw_their_own_radiance(tmp_path, monkeypatch):
    from study.impostor import capture
    from study.measure import inputs

    calls = {"distance": 0, "radiance": 0}

    def counted(name, fn):
        def wrapped(*a, **k):
            calls[name] += 1
            return fn(*a, **k)

        return wrapped

    monkeypatch.setattr(inputs, "capture_distance", counted("distance", capture.capture_distance))
    monkeypatch.setattr(inputs, "render_cube", counted("radiance", capture.render_cube))
    cache = Cache(tmp_path)
    sc = _scene(cube_res=8, cube_spp=1)
    a = inputs.impostor(sc, cache)
    b = inputs.impostor(sc.with_updates({"render.seed": 5}), cache)
    assert calls == {"distance": 1, "radiance": 2}  # the seed redraws the path-traced radiance only
    np.testing.assert_array_equal(a.distance, b.distance)
    assert not np.array_equal(a.radiance, b.radiance)
    # another reference point is another capture of distances
    inputs.impostor(sc.with_updates({"reference.point": [0.2, 1.4, 0.0]}), cache)
    assert calls["distance"] == 2


def test_reproduce_estimate_names_every_command_and_counts_the_unmodelled_ones(tmp_path, capsys, monkeypatch):
    """scripts/reproduce.sh's estimate: one line per command, the ones the stage model does not count (caustics,
    animation, convergence) from their last run's metadata.json seconds, and a total that includes them (before:
    one line that left them out)."""
    (tmp_path / "animation").mkdir()
    (tmp_path / "animation" / "metadata.json").write_text(
        json.dumps({"seconds": 600.0, "backend": "numpy", "cpus": 2})
    )
    steps = estimate.step_estimates(
        ["figure fig_attic", "animate", "caustics-sweep", "convergence"], cache=Cache(None), reports=tmp_path
    )
    by = {c: (s, how) for c, s, how in steps}
    assert by["animate"] == (600.0, "its last run, numpy on 2 cores")
    assert by["caustics-sweep"][0] is None and by["convergence"][0] is None
    fig = by["figure fig_attic"][0]
    assert (
        fig
        == estimate.config_estimate(
            estimate.Path("configs/fig_attic.toml").resolve(), cache=Cache(None)
        ).seconds
    )
    assert estimate.wall(steps, 2) == max((fig + 600.0) / 2, fig, 600.0)
    assert estimate.wall([("a", 100.0, ""), ("b", 10.0, ""), ("c", None, "")], 2) == 100.0
    monkeypatch.setattr(
        estimate, "measured", lambda cmd, reports=None: (60.0, "x") if cmd == "animate" else None
    )
    estimate.main(["--jobs", "2", "--cache", str(tmp_path / "c"), "animate", "convergence"])
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "  animate: about 1 min 0 s (x)" and out[1].startswith("  convergence: unknown")
    assert (
        out[2].startswith("estimate: about 1 min 0 s wall for 2 commands on 2 cores")
        and "not counted: convergence" in out[2]
    )
