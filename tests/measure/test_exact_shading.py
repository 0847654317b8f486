"""Exact shading (:func:`study.measure.inputs.exact_shading`, ``Captured.shade``): on the case's exact rays it hands
back truth_at_hit's own values (the rays in the case's order, up to the float32 rounding of the methods' copies);
every other ray is path traced by Mitsuba with exact shading's own seed, as before; a rough object's truth is its
lobe's average, so there every ray is path traced. The truth's values are planted (a sentinel no render gives),
the path-traced ones are compared with Mitsuba called directly."""

import numpy as np
import pytest

from study.measure import inputs, truth
from study.reference.mitsuba import radiance_along
from study.scene import scene_from_dict
from tests.conftest import small_scene_dict

SENTINEL = -7.0  # radiance no render gives: where it shows, the truth's planted value was handed back


def _rays(n=300, seed=0):
    rng = np.random.default_rng(seed)
    o = rng.uniform([-1.5, 0.5, -1.5], [1.5, 2.5, 1.5], (n, 3))
    d = rng.normal(size=(n, 3))
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def _own(scene, o, d):
    return radiance_along(scene, o, d, spp=scene.render.spp, seed=scene.render.seed + 2 * truth.SEED_OFFSET)


@pytest.fixture(scope="module")
def scene():
    return scene_from_dict(small_scene_dict())


def test_the_exact_rays_get_the_truths_values_others_are_path_traced(scene):
    o, d = _rays()
    along = np.full((len(o), 3), SENTINEL, np.float32)
    planted = lambda: (o, d, along)  # noqa: E731
    ref = np.asarray(scene.reference.point, float)
    o32 = (o - ref).astype(np.float32).astype(np.float64) + ref  # a method's float32 copy, relative to o
    d32 = d.astype(np.float32).astype(np.float64)
    np.testing.assert_array_equal(inputs.exact_shading(scene, o32, d32, planted), along)

    off = d + np.array([0.0, 1e-3, 0.0])  # half the rays turned by 1 mrad: other rays
    moved = np.arange(len(o)) % 2 == 1
    d_mix = np.where(moved[:, None], off / np.linalg.norm(off, axis=1, keepdims=True), d32)
    got = inputs.exact_shading(scene, o32, d_mix, planted)
    np.testing.assert_array_equal(got[~moved], along[~moved])
    assert (got[moved] >= 0).all()
    np.testing.assert_array_equal(got[moved], _own(scene, o32[moved], d_mix[moved]))


def test_other_rays_than_the_cases_are_path_traced_as_without_the_truth(scene):
    o, d = _rays(seed=1)
    planted = lambda: (o, d, np.full((len(o), 3), SENTINEL, np.float32))  # noqa: E731
    sub = inputs.exact_shading(
        scene, o[:-1], d[:-1], planted
    )  # another set (one ray fewer): none is the case's
    np.testing.assert_array_equal(sub, _own(scene, o[:-1], d[:-1]))
    np.testing.assert_array_equal(inputs.exact_shading(scene, o, d, None), _own(scene, o, d))
    rough = scene.with_updates({"object.alpha": 0.25})  # the truth is the lobe's average, not along the ray
    np.testing.assert_array_equal(inputs.exact_shading(rough, o, d, planted), _own(rough, o, d))


def test_same_rays_is_within_float_rounding_of_the_scenes_size():
    o, d = _rays(50, seed=2)
    size = 10.0
    assert truth.same_rays(o, d, o + 0.5e-5 * size, d, size).all()
    assert not truth.same_rays(o, d, o + 2e-5 * size, d, size).any()
    assert not truth.same_rays(o, d, o, d + 2e-5, size).any()
    assert not truth.same_rays(o, d, o[:-1], d[:-1], size).any()
    assert truth.same_rays(o, d, o, d, size).dtype == bool


def test_the_estimate_prices_no_path_traced_set_for_the_exact_query_on_a_mirror(scene):
    """study's time estimate (:func:`study.harness.budget.estimate`): traced on a mirror reads the truth's values,
    so its renders cost what classical's do; sdf(shading="exact") still path traces a set of rays of its own, and
    so does traced on a glass object (its rays through the distance map are not the exact ones)."""
    from study import methods
    from study.harness import budget

    def renders(sc, *ms):
        return budget.estimate(sc, [methods.make("classical"), *ms]).time["render.spp"]

    base = renders(scene)
    assert renders(scene, methods.make("traced")) == base
    assert renders(scene, methods.make("sdf", shading="exact")) > base
    glass = scene.with_updates({"object.material": {"type": "dielectric", "ior": 1.5}})
    assert renders(glass, methods.make("traced")) > renders(glass)
