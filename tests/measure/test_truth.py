"""The truth references (study/measure/truth.py): truth_at_hit against analytic radiance, the noise-debiased
RMSE, relMSE and the error decomposition on constructed images."""

import numpy as np
import pytest

from study.measure import truth as T
from study.reference import mitsuba as mref
from study.scene import scene_from_dict
from tests.conftest import small_scene_dict


def test_truth_at_hit_of_a_constant_radiance_surface_is_that_radiance(monkeypatch):
    """Inside a sphere that emits L = (0.3, 0.5, 0.7) and reflects nothing, every ray sees exactly L."""
    L = [0.3, 0.5, 0.7]
    real = mref.scene_dict

    def emitting_sphere(scene, *, with_object, sensor, integrator=None):
        d = {
            k: v
            for k, v in real(scene, with_object=False, sensor=sensor, integrator=integrator).items()
            if k in ("type", "sensor", "integrator")
        }
        d["shell"] = {
            "type": "sphere",
            "radius": 10.0,
            "flip_normals": True,
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": L}},
        }
        return d

    monkeypatch.setattr(mref, "scene_dict", emitting_sphere)
    scene = scene_from_dict(small_scene_dict())
    rng = np.random.default_rng(0)
    o = rng.uniform(-1, 1, (500, 3))
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rad = mref.radiance_along(scene, o, d, spp=4, seed=3)
    np.testing.assert_allclose(rad, np.broadcast_to(L, rad.shape), rtol=1e-5)


def test_debiased_rmse_removes_known_noise():
    """A test image = truth + noise of known σ: the raw RMSE is σ, the debiased one ≈ 0; with an extra offset δ
    the debiased RMSE recovers δ."""
    rng = np.random.default_rng(1)
    truth = rng.uniform(0, 1, (64, 64, 3))
    sigma = 0.05
    noisy = truth + rng.normal(0, sigma, truth.shape)
    raw = float(np.sqrt(np.mean((noisy - truth) ** 2)))
    assert raw == pytest.approx(sigma, rel=0.05)
    assert T.debiased(raw, sigma) < 0.01
    off = float(np.sqrt(np.mean((noisy + 0.1 - truth) ** 2)))
    assert T.debiased(off, sigma) == pytest.approx(0.1, rel=0.05)


def test_relmse_is_relative():
    a, b = np.full((4, 4, 3), 2.0), np.full((4, 4, 3), 1.0)
    m = np.ones((4, 4), bool)
    assert T.relmse(a, b, m) == pytest.approx(1.0 / (1.0 + T.REL_EPS))


def test_real_case_oracle_map_is_near_the_truth(tmp_path):
    """A small case of the real pipeline: oracle_map vs truth_at_hit (noise-debiased) is well below oracle_map vs
    Mitsuba's camera render (which carries the object's shadow and one bounce less on the reflected path), and
    classical's search error is far above localized's."""
    from study import methods
    from study.cache import Cache
    from study.measure.case import run_case

    d = small_scene_dict()
    d["render"].update(spp=64, cube_spp=64)  # noise well below the systematic parts
    scene = scene_from_dict(d)
    ms = [methods.make("classical"), methods.make("localized", iterations=1), methods.make("localized")]
    rows = {r["label"]: r for r in run_case(scene, ms, cache=Cache(tmp_path), keep_images=True).rows}
    for m in ms:
        assert rows[m.label]["dec_sums"] == 1, m.label
    ref = rows["oracle_map"]
    assert ref["rmse_truth_debiased"] < 0.7 * ref["rmse_mitsuba_debiased"]
    assert rows["classical"]["dec_search"] > 25 * rows[methods.make("localized").label]["dec_search"]
