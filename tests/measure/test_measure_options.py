"""The two render keys that make fig4 cheaper on a CPU: ``render.flip_against`` (FLIP against the listed references
only: the others' flip columns are NaN, every other column the same) and ``render.probe_spp`` (multi_probe's probes
rendered at their own sample count, cached under that count; unset: the impostor's cube_spp, the cache key of
before)."""

import numpy as np
import pytest

import study
from study.api import load_scene
from study.cache import Cache
from study.impostor import probes
from study.impostor.capture import impostor_key
from study.impostor.views import ProbeSpec
from study.reference.tracer import make_tracer
from tests.conftest import small_scene_dict

TINY = {"render.cube_res": 16, "camera.width": 32, "camera.height": 32}


def test_flip_against_the_truth_alone(tmp_path):
    cache = tmp_path / "cache"
    every = {**TINY, "render.flip_against": ["oracle", "truth", "mitsuba"]}
    full = study.evaluate(small_scene_dict(), ["classical"], overrides=every, cache=cache).table
    only = study.evaluate(
        small_scene_dict(), ["classical"], overrides={**TINY, "render.flip_against": ["truth"]}, cache=cache
    ).table
    assert np.isfinite(full["flip_mitsuba"]).all() and np.isfinite(full["flip_oracle"]).all()
    assert only["flip_mitsuba"].isna().all() and only["flip_oracle"].isna().all()
    for col in full.columns:  # everything else as before (the seconds a method took aside)
        if col.startswith(("flip_mitsuba", "flip_oracle")) or col == "seconds" or full[col].dtype == object:
            continue
        np.testing.assert_array_equal(full[col].to_numpy(), only[col].to_numpy(), err_msg=col)


def test_a_bad_flip_reference_is_refused():
    with pytest.raises(Exception, match="flip_against"):
        load_scene(small_scene_dict(), overrides={"render.flip_against": ["embree"]})


@pytest.mark.parametrize("probe_spp", [None, 2])
def test_probes_render_at_probe_spp(tmp_path, monkeypatch, probe_spp):
    calls = []

    def fake_render(scene, res, spp, loaded=None):
        calls.append(spp)
        return np.zeros((6, res, res, 3), np.float32)

    monkeypatch.setattr(probes, "render_cube", fake_render)
    sc = load_scene(small_scene_dict(), overrides={**TINY, "render.probe_spp": probe_spp})
    tracer = make_tracer(sc.mesh())
    texels0 = np.zeros((6, 16, 16, 4), np.float32)
    tex, centres = probes.capture_probes(sc, ProbeSpec(grid=(2, 1, 1)), Cache(tmp_path), texels0, tracer)
    want = probe_spp or sc.render.cube_spp
    assert calls and set(calls) == {want} and len(calls) == len(centres) - 1
    calls.clear()  # cached under its own count: the same again renders nothing, another count renders again
    probes.capture_probes(sc, ProbeSpec(grid=(2, 1, 1)), Cache(tmp_path), texels0, tracer)
    assert calls == []
    other = sc.with_updates({"render.probe_spp": want + 1})
    probes.capture_probes(other, ProbeSpec(grid=(2, 1, 1)), Cache(tmp_path), texels0, tracer)
    assert set(calls) == {want + 1}
    at = sc.with_updates({"reference.point": [float(c) for c in centres[1]]})
    if probe_spp is None:  # unset: the key an impostor taken there has always had
        assert impostor_key(at, spp=want) == impostor_key(at)


def test_the_hardly_visible_claim_skips_a_table_without_flip_against_the_oracle():
    """With render.flip_against leaving the oracle out, flip_oracle_p95 is NaN: the claim is not judged on that
    table (None), rather than failing on NaN; with numbers it is judged both ways (p95 ≤ 0.05 holds)."""
    from study.methods import make
    from study.report.claims import hardly_visible

    loc = make("localized").label

    def rows(p95):
        return [
            {"case": "c", "label": loc, "flip_oracle_p95": p95, "flip_oracle": p95 / 2, "held_pixels": 100}
        ]

    assert hardly_visible(rows(float("nan"))) is None
    v = hardly_visible(rows(0.004))  # measured, never judged: FLIP states no just-noticeable value
    assert v is not None and v.ok is None and "0.004 (c" in v.number
    v = hardly_visible(rows(0.2))
    assert v is not None and v.ok is None and v.number.startswith("worst p95 FLIP vs the oracle 0.2")


def test_seeds_of_one_geometry_read_one_probe_distance_capture(tmp_path, monkeypatch):
    """A second seed of one geometry redraws its probes' path-traced radiance but reads their exact distances from
    the first seed's capture, with the same values (before: the distances were keyed with the seed and traced
    again); another probe resolution traces them anew."""
    calls = {"radiance": 0, "distance": 0}

    def fake_render(scene, res, spp, loaded=None):
        calls["radiance"] += 1
        return np.full((6, res, res, 3), scene.render.seed, np.float32)

    def counted(tracer, p, res, **k):
        calls["distance"] += 1
        return distances_from(tracer, p, res, **k)

    from study.impostor.capture import distances_from

    monkeypatch.setattr(probes, "render_cube", fake_render)
    monkeypatch.setattr(probes, "distances_from", counted)
    sc = load_scene(small_scene_dict(), overrides=TINY)
    tracer = make_tracer(sc.mesh())
    texels0 = np.zeros((6, 16, 16, 4), np.float32)
    a, centres = probes.capture_probes(sc, ProbeSpec(grid=(2, 1, 1)), Cache(tmp_path), texels0, tracer)
    n = len(centres) - 1
    assert n >= 1 and calls == {"radiance": n, "distance": n}
    b, _ = probes.capture_probes(
        sc.with_updates({"render.seed": 3}), ProbeSpec(grid=(2, 1, 1)), Cache(tmp_path), texels0, tracer
    )
    assert calls == {"radiance": 2 * n, "distance": n}
    np.testing.assert_array_equal(a[1:, ..., 3], b[1:, ..., 3])  # the distances: one capture, the same values
    assert not np.array_equal(a[1:, ..., :3], b[1:, ..., :3])  # the radiance: drawn per seed
    np.testing.assert_array_equal(b[1, ..., 3], distances_from(tracer, centres[1], sc.render.cube_res))


def test_a_probe_set_s_probes_render_in_one_mitsuba_scene_as_each_in_its_own():
    """render_cube with a shared ``loaded`` (capture_probes: one Mitsuba scene for every probe) gives each probe's
    radiance bit for bit as a scene built for it alone, and builds the scene once."""
    from study.impostor import capture
    from study.reference import mitsuba as mitsuba_ref

    sc = load_scene(small_scene_dict(), overrides=TINY)
    points = [[-0.5, 1.0, 0.2], [0.6, 1.4, -0.3]]
    built = []
    real = mitsuba_ref.scene_dict
    try:
        mitsuba_ref.scene_dict = lambda *a, **k: built.append(1) or real(*a, **k)
        loaded = {}
        shared = [capture.render_cube(sc.with_updates({"reference.point": p}), 8, 4, loaded) for p in points]
        assert len(built) == 1
        alone = [capture.render_cube(sc.with_updates({"reference.point": p}), 8, 4) for p in points]
        assert len(built) == 3
    finally:
        mitsuba_ref.scene_dict = real
    assert not np.array_equal(alone[0], alone[1])  # two places, two cube maps
    for a, b in zip(shared, alone):
        np.testing.assert_array_equal(a, b)
