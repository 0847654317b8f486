"""The image columns as array code (study.measure.pixels) against their twins, the reference path of backend
numpy: RMSE, PSNR and SSIM of study.measure.metrics (PSNR and SSIM by scikit-image, SSIM on the same crop with
scipy's reflected borders) and the truth's columns of study.measure.truth (RMSE, relMSE, the noise RMS, the
debiased RMSE), on synthetic images (noise, flat and equal images, a step, the mask at the frame's edge and
corner, NaN off the mask, a frame barely larger than the window) and on study images; each within 1e-5 (seen:
float64 rounding, ≤ 1e-12). The case's own calls (metrics.image_errors, truth.columns with backend 'llvm') take
this path, and backend 'numpy' stays scikit-image's."""

from pathlib import Path

import numpy as np
import pytest

import study
from study.measure import metrics, pixels, truth
from tests.conftest import BACKENDS, small_scene_dict

pytestmark = pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")
TOL = 1e-5


@pytest.fixture(autouse=True)
def llvm_at_every_size(monkeypatch):
    """The case's calls with backend llvm take the array code on these small images too (not only from
    metrics.LLVM_MIN_PIXELS on, where it is the faster)."""
    monkeypatch.setattr(metrics, "LLVM_MIN_PIXELS", 0)


def disc(h, w, cy, cx, r):
    yy, xx = np.mgrid[:h, :w]
    return (yy - cy) ** 2 + (xx - cx) ** 2 < r * r


def synthetic():
    rng = np.random.default_rng(3)
    a = rng.random((64, 72, 3)) * 1.4  # HDR: some values clip in the LDR metrics
    b = a + rng.normal(0, 0.05, a.shape)
    yield "noise, disc inside", a, b, disc(64, 72, 30, 35, 14)
    yield (
        "noise, disc at the edge",
        a,
        b,
        disc(64, 72, 2, 70, 12),
    )  # the crop meets the frame: reflected borders
    yield "noise, whole frame", a, b, np.ones((64, 72), bool)
    yield "noise, 2×2 mask", a, b, np.pad(np.ones((2, 2), bool), ((20, 42), (9, 61)))
    flat = np.full((40, 40, 3), 0.3)
    yield "equal images (PSNR inf)", flat, flat.copy(), disc(40, 40, 20, 20, 8)
    step = flat.copy()
    step[:, 20:] = (0.7, 0.2, 0.5)
    yield "a step in colour", flat, step, disc(40, 40, 20, 20, 9)
    nan = b.copy()
    nan[:5] = np.nan  # off the mask and outside its crop: no effect, as in numpy
    yield "NaN off the mask", a, nan, disc(64, 72, 40, 35, 10)
    yield "a frame 9 px tall", a[:9, :20], b[:9, :20], disc(9, 20, 4, 10, 3)


def numpy_errors(ref, test, mask):
    return (
        metrics.rmse(ref, test, mask=mask),
        metrics.psnr(ref, test, mask=mask),
        metrics.ssim(ref, test, mask=mask),
    )


def assert_close(got, want):
    for g, w in zip(got, want):
        assert (g == w) if np.isinf(w) else abs(g - w) <= TOL, (got, want)


@pytest.mark.parametrize("case", list(synthetic()), ids=lambda c: c[0])
def test_synthetic_images_match_scikit_image(case):
    _, ref, test, mask = case
    want = numpy_errors(ref, test, mask)
    assert_close(pixels.errors_on(ref, test, mask=mask, backend="llvm"), want)  # the whole frame
    got = metrics.image_errors(
        ref, test, mask=mask, suffix="x", backend="llvm", with_flip=False
    )  # SSIM's crop
    assert_close([got[f"{m}_x"] for m in ("rmse", "psnr", "ssim")], want)


def test_empty_mask_is_nan():
    a = np.zeros((10, 10, 3))
    assert np.isnan(pixels.errors_on(a, a, mask=np.zeros((10, 10), bool), backend="llvm")).all()


def fake_truth(img, rng):
    return truth.Truth(
        image=img,
        noise=rng.normal(0, 0.02, img.shape),
        along=np.zeros((1, 3)),
        mitsuba_noise=rng.normal(0, 0.03, img.shape),
    )


@pytest.mark.parametrize("case", list(synthetic())[:4], ids=lambda c: c[0])
def test_truth_columns_match_numpy(case):
    _, ref, test, mask = case
    rng = np.random.default_rng(5)
    t, mitsuba = fake_truth(ref, rng), ref + rng.normal(0, 0.1, ref.shape)
    want = truth.columns(test, t, mitsuba, mask=mask)
    got = truth.columns(test, t, mitsuba, mask=mask, backend="llvm")
    assert got.keys() == want.keys()
    for k in want:
        assert abs(got[k] - want[k]) <= TOL * max(1.0, abs(want[k])), (k, got[k], want[k])


@pytest.fixture(scope="module")
def study_images(tmp_path_factory):
    return study.evaluate(
        small_scene_dict(),
        ["classical", "localized(iterations=3)"],
        overrides={"render.cube_res": 16, "camera.width": 48, "camera.height": 40},
        cache=tmp_path_factory.mktemp("cache"),
    )


def test_study_images_match_scikit_image(study_images):
    r = study_images
    for ref in ("truth_at_hit", "mitsuba", "oracle_map"):
        for label in ("classical", "localized(iterations=3)"):
            ref_img, img = r.images[ref], r.images[label]
            assert_close(pixels.errors_on(ref_img, img, mask=r.mask, backend="llvm"),
                         numpy_errors(ref_img, img, r.mask))  # fmt: skip
            # the case's call: image_errors on backend llvm measures there, on numpy with scikit-image
            kw = dict(mask=r.mask, suffix="x", with_flip=False)
            got = metrics.image_errors(ref_img, img, backend="llvm", **kw)
            want = metrics.image_errors(ref_img, img, backend="numpy", **kw)
            assert_close([got[f"{m}_x"] for m in ("rmse", "psnr", "ssim")],
                         [want[f"{m}_x"] for m in ("rmse", "psnr", "ssim")])  # fmt: skip
    rng = np.random.default_rng(9)
    t = fake_truth(r.images["truth_at_hit"], rng)
    img = r.images["classical"]
    want = truth.columns(img, t, r.images["mitsuba"], mask=r.mask)
    got = truth.columns(img, t, r.images["mitsuba"], mask=r.mask, backend="llvm")
    for k in want:
        assert abs(got[k] - want[k]) <= TOL * max(1.0, abs(want[k])), k


def test_where_the_columns_are_measured(monkeypatch):
    assert metrics.image_backend("numpy") == "numpy"  # the reference path
    assert metrics.image_backend("cuda", 10) == "cuda"
    monkeypatch.setattr(metrics, "LLVM_MIN_PIXELS", 10_000)
    assert metrics.image_backend("llvm", 10_000) == metrics.LLVM_IMAGES
    assert metrics.image_backend("llvm", 9_999) == "numpy"  # small crops: scikit-image is the faster
    calls = []
    real = pixels.errors_on
    monkeypatch.setattr(pixels, "errors_on", lambda *a, **k: calls.append(1) or real(*a, **k))
    a = np.random.default_rng(1).random((160, 160, 3))
    for r, want in ((20, 0), (60, 1)):  # crops of (2r + 16)² pixels: 56² below the threshold, 136² above
        metrics.image_errors(
            a, a * 0.9, mask=disc(160, 160, 80, 80, r), suffix="x", backend="llvm", with_flip=False
        )
        assert len(calls) == want


def test_the_bench_script_writes_its_table(tmp_path):
    import runpy

    bench = runpy.run_path(str(Path(__file__).resolve().parents[2] / "scripts" / "bench_image_columns.py"))
    out = tmp_path / "image-columns-cpu.md"
    bench["main"](["--sizes", "40", "--repeats", "1", "--out", str(out)])
    text = out.read_text()
    assert "| 40² |" in text and f"measures these columns on **{metrics.LLVM_IMAGES}** from crops of" in text
    assert metrics.LLVM_MIN_PIXELS == 0  # the fixture's; the script says the rule's own threshold
    assert "LLVM / flip-evaluator" in text  # FLIP's ratio beside it
