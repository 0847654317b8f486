"""The array LDR-FLIP (study.measure.flip) against flip-evaluator, the reference (NVIDIA's C++ code, pip package):
on study images (a small scene's method renders against its truth_at_hit, and Mitsuba's render) and on synthetic
ones (noise, steps in luminance and in chroma only, flat colours, black/white extremes), the mean error and the
per-pixel 99th percentile agree within 1e-4 on numpy and on Dr.Jit's LLVM backend; and the study's FLIP columns
are the same whichever implementation made them (study.measure.metrics.flip_map with backend="llvm")."""

import flip_evaluator
import numpy as np
import pytest

import study
from study.measure import metrics
from study.measure.flip import feature_filter, ldr_flip_image, spatial_filters
from tests.conftest import BACKENDS, small_scene_dict

TOL = 1e-4


def reference(ref, test):
    emap, _, _ = flip_evaluator.evaluate(
        np.ascontiguousarray(ref, np.float32), np.ascontiguousarray(test, np.float32), "LDR", applyMagma=False
    )
    return np.asarray(emap, np.float32)[..., 0]


def assert_matches(ref, test, backend):
    want, got = reference(ref, test), ldr_flip_image(ref, test, backend)
    assert got.shape == want.shape
    assert abs(got.mean() - want.mean()) <= TOL, (got.mean(), want.mean())
    assert abs(np.percentile(got, 99) - np.percentile(want, 99)) <= TOL
    assert np.abs(got - want).max() <= 1e-3  # no pixel far off either (seen: ≤ 1e-5)


def synthetic():
    rng = np.random.default_rng(7)
    noise = rng.random((48, 56, 3)).astype(np.float32)
    yield "noise", noise, np.clip(noise + rng.normal(0, 0.08, noise.shape), 0, 1)
    step = np.full((40, 40, 3), 0.5, np.float32)
    up = step.copy()
    up[:20] = 0.62
    yield "luminance step", step, up
    chroma = step.copy()
    chroma[:, 20:] = (0.62, 0.45, 0.5)  # a step in colour
    yield "chroma step", step, chroma
    yield "flat", np.full((24, 30, 3), 0.3, np.float32), np.full((24, 30, 3), 0.31, np.float32)
    bw = np.zeros((32, 32, 3), np.float32)
    bw[::4] = 1.0
    yield "black/white lines", bw, 1 - bw


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", list(synthetic()), ids=lambda c: c[0])
def test_synthetic_images_match_flip_evaluator(case, backend):
    _, ref, test = case
    assert_matches(ref, test, backend)


@pytest.fixture(scope="module")
def study_images(tmp_path_factory):
    r = study.evaluate(
        small_scene_dict(),
        ["classical", "localized(iterations=3)"],
        overrides={"render.cube_res": 16, "camera.width": 48, "camera.height": 40},
        cache=tmp_path_factory.mktemp("cache"),
    )
    return r


@pytest.mark.parametrize("backend", BACKENDS)
def test_study_images_match_flip_evaluator(study_images, backend):
    truth = metrics.to_ldr(study_images.images["truth_at_hit"])
    for label in ("classical", "localized(iterations=3)", "mitsuba"):
        assert_matches(truth, metrics.to_ldr(study_images.images[label]), backend)


def test_the_measured_column_is_the_same_with_the_array_flip(study_images):
    r = study_images
    truth, img, mask = r.images["truth_at_hit"], r.images["classical"], r.mask
    want = metrics.flip(truth, img, mask=mask)
    assert metrics.flip(truth, img, mask=mask, backend="llvm") == pytest.approx(want, abs=TOL)
    assert want == pytest.approx(float(r.table.set_index("label").loc["classical", "flip_truth"]), rel=1e-6)


def test_filters_are_normalised():
    """The CSF filters of Y and Cx sum to 1, Cz's two to unit length together; the feature filter's Gaussian sums to
    1 and its derivatives' positive and negative weights to ±1 (FLIP's normalisation); radii at 67 ppd: 10 and 9."""
    ycx, cz = spatial_filters()
    assert ycx.shape == (21, 2) and np.allclose(ycx.sum(0), 1, atol=1e-6)
    assert np.hypot(*cz.sum(0)) == pytest.approx(1, abs=1e-6)
    f = feature_filter()
    assert f.shape == (19, 3) and f[:, 0].sum() == pytest.approx(1, abs=1e-6)
    for c in (1, 2):
        assert f[f[:, c] > 0, c].sum() == pytest.approx(1, abs=1e-6)
        assert f[f[:, c] < 0, c].sum() == pytest.approx(-1, abs=1e-6)


@pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")
def test_a_case_measured_on_llvm_matches_numpy(study_images, tmp_path):
    """The same small case with --backend llvm: the reference rows (which no method's float32 search touches) have
    the numpy run's outcome columns exactly (classes on the device) and its FLIP columns within 1e-4 (the array
    FLIP against flip-evaluator)."""
    r = study.evaluate(
        small_scene_dict(),
        ["classical", "localized(iterations=3)"],
        backend="llvm",
        overrides={"render.cube_res": 16, "camera.width": 48, "camera.height": 40},
        cache=tmp_path / "cache",
    )
    a, b = study_images.table.set_index("label"), r.table.set_index("label")
    for label in ("oracle_map", "truth_at_hit"):
        for col in ("wrong_fraction", "wrong_depth_fraction", "no_hit_fraction", "dist_p95", "rmse_truth"):
            assert b.loc[label, col] == a.loc[label, col] or (
                np.isnan(a.loc[label, col]) and np.isnan(b.loc[label, col])
            )
        for col in ("flip_oracle", "flip_truth"):  # the default references (render.flip_against)
            assert b.loc[label, col] == pytest.approx(a.loc[label, col], abs=TOL)
    for label in (
        "classical",
        "localized(iterations=3)",
    ):  # the methods: float32 searches, same images to 1e-4
        assert b.loc[label, "flip_truth"] == pytest.approx(a.loc[label, "flip_truth"], abs=1e-3)


@pytest.mark.parametrize("backend", [b for b in BACKENDS if b != "numpy"])
def test_linear_images_are_encoded_on_the_device(backend):
    """flip_map on a device takes linear radiance and encodes it to sRGB there (float32): it matches
    flip-evaluator on the CPU's float64 encoding, with values above 1 (clipped) and about the encoding's knee."""
    rng = np.random.default_rng(11)
    ref = rng.uniform(0, 2.0, (36, 44, 3)) * (rng.random((36, 44, 1)) < 0.5) + 0.003 * rng.random((36, 44, 3))
    test = np.abs(ref + rng.normal(0, 0.05, ref.shape))
    want = reference(metrics.to_ldr(ref), metrics.to_ldr(test))
    got = metrics.flip_map(ref, test, backend)
    assert abs(got.mean() - want.mean()) <= TOL and np.abs(got - want).max() <= 1e-3
