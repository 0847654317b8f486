"""The batched image columns (study.measure.batched) against the per-method path they replace: the same case run
both ways, row by row, and the pieces against their references on planted images."""

import math
import threading
from types import SimpleNamespace

import numpy as np
import pytest

from study import methods as registry
from study.cache import Cache
from study.measure import batched, case, metrics
from study.measure.case import run_case
from study.scene import scene_from_dict
from tests.conftest import BACKENDS, small_scene_dict

#: relative tolerance of the batched means (sums over a stack's axis may round differently in the last bits)
REL = 1e-9  # (numpy: the same bits; the tolerance is for llvm)


def _per_method(images, r, *, backend, intervals):
    """The per-method path as it stood: one image at a time, the whole frame's FLIP map against the truth."""
    cols, maps = [], []
    for img in images:
        fmap = metrics._flip_frame(r.truth.image, img, backend) if intervals else None
        t = SimpleNamespace(image=img, over=None, reference="")
        cols.append(case._image_columns(t, r, fmap, backend, intervals)())
        maps.append(fmap)
    return cols, maps


def _close(a, b, rel=REL, abs_=1e-12):
    if isinstance(a, float) or isinstance(b, float):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return a == b or abs(a - b) <= abs_ + rel * max(abs(a), abs(b))
    return a == b


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return Cache(tmp_path_factory.mktemp("batched-cache"))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("intervals", [True, False])
def test_a_case_measures_the_same_batched_as_method_by_method(backend, intervals, cache, monkeypatch):
    # a column hides part of what the sphere reflects from the reference point, so the oracle leaves pixels out
    # and each method's oracle reference differs (its unheld pixels take the image's value)
    d = small_scene_dict(columns=[{"center": [0.3, -0.7], "footprint": [0.6, 0.6], "height": 1.75},
                                  {"center": [1.3, -0.5], "footprint": [0.5, 0.5], "height": 1.9}])  # fmt: skip
    d["object"]["center"], d["camera"]["target"], d["camera"]["fov"] = [0.3, 2.3, 0.3], [0.3, 2.1, 0.3], 60.0
    d["render"]["flip_against"] = ["oracle", "truth", "mitsuba"]
    scene = scene_from_dict(d)
    ms = [registry.make(n) for n in ("classical", "proxy_box", "layered")]
    ms.append(registry.make("localized", iterations=3))
    fast = run_case(scene, ms, backend=backend, cache=cache, intervals=intervals)
    monkeypatch.setattr(batched, "method_columns", _per_method)
    slow = run_case(scene, ms, backend=backend, cache=cache, intervals=intervals)
    assert [r["label"] for r in fast.rows] == [r["label"] for r in slow.rows]
    assert any(r["unheld_pixels"] > 0 for r in slow.rows)  # the oracle's pixels differ from the truth's
    for a, b in zip(fast.rows, slow.rows):
        assert list(a) == list(b)  # the same columns, in the same order
        rel = 0.0 if backend == "numpy" else REL  # numpy: bit for bit
        bad = [k for k in a if k not in ("seconds", "case_seconds") and not _close(a[k], b[k], rel, rel)]
        assert not bad, [(k, a[k], b[k]) for k in bad]
    for label, fmap in slow.flip_maps.items():
        if fmap is None:
            assert fast.flip_maps[label] is None
        elif backend == "numpy":  # flip-evaluator on the crop where the images differ: bit for bit
            np.testing.assert_array_equal(fast.flip_maps[label], fmap)
        else:  # the array code over the stack: float32 rounding
            np.testing.assert_allclose(fast.flip_maps[label], fmap, atol=1e-6)


def _planted(n=48, seed=3):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:n, :n]
    mask = (yy - 0.45 * n) ** 2 + (xx - 0.55 * n) ** 2 < (0.25 * n) ** 2
    ref = rng.random((n, n, 3)) * 1.4
    tests = np.repeat(ref[None], 4, axis=0)
    tests[0][mask] += 0.3  # a brighter object
    tests[1][mask] = rng.random((int(mask.sum()), 3))  # noise
    tests[2][mask & (xx < n // 2)] *= 0.2  # half darker
    # tests[3]: identical to the reference (PSNR inf, FLIP 0)
    return ref, tests, mask


def test_image_errors_of_a_stack_are_each_images():
    ref, tests, mask = _planted()
    got = batched.errors(ref, tests, mask=mask, suffix="x", backend="numpy", with_flip=True)
    for img, g in zip(tests, got):
        want = metrics.image_errors(ref, img, mask=mask, suffix="x")
        assert g.keys() == want.keys()
        assert all(_close(g[k], want[k]) for k in g), (g, want)
    assert got[3]["psnr_x"] == math.inf and got[3]["flip_x"] == 0.0
    # each image with a reference of its own (the oracle's case): the same as one at a time
    refs = tests[[1, 0, 3, 2]]
    got = batched.errors(ref, tests, mask=mask, suffix="x", backend="numpy", with_flip=True, refs=refs)
    for img, r, g in zip(tests, refs, got):
        want = metrics.image_errors(r, img, mask=mask, suffix="x")
        assert all(_close(g[k], want[k]) for k in g if not k.startswith(("rmse", "psnr"))), (g, want)


def test_flip_map_on_the_differing_crop_is_the_whole_frames():
    ref, tests, mask = _planted(n=96)
    for img in tests:
        np.testing.assert_array_equal(metrics.flip_map(ref, img), metrics._flip_frame(ref, img, "numpy"))
    assert not metrics.flip_map(ref, tests[3]).any()


@pytest.mark.skipif("llvm" not in BACKENDS, reason="Dr.Jit LLVM not available")
def test_flip_stack_is_each_pairs_array_flip():
    from study.measure import flip

    ref, tests, _ = _planted(n=40)
    stack = flip.flip_stack(ref, tests, "llvm")
    for img, got in zip(tests, stack):
        np.testing.assert_allclose(got, flip.ldr_flip_image(ref, img, "llvm", linear=True), atol=1e-6)
    # images stacked are filtered each with its own edges: a bright first row of one image leaks into no other
    np.testing.assert_allclose(flip.flip_stack(ref, tests[2:3], "llvm")[0], stack[2], atol=1e-6)


def test_the_stack_differs_where_some_image_differs():
    # the union over the stack of metrics.differing, with NaN equal to NaN and −0.0 equal to 0.0 (a bitwise or a
    # NaN-blind comparison fails it), against one reference and against one reference per image
    rng = np.random.default_rng(3)
    ref = rng.random((9, 11, 3)).astype(np.float32)
    ref[1, 2, 0], ref[4, 4, 1] = np.nan, 0.0
    tests = np.repeat(ref[None], 4, 0)
    tests[0, 5, 6, 2] += 0.5  # differs
    tests[1, 4, 4, 1] = -0.0  # equal as values
    tests[2, 7, 1, 0] = np.nan  # differs (a value against NaN)
    tests[3, 1, 2, 0] = np.float32("nan") * -1  # NaN against NaN: equal
    per = np.stack([ref, ref, ref + 0, ref])
    per[3, 0, 0, 0] += 1.0  # the fourth image's own reference differs there
    for r in (ref, per):
        want = np.any(
            [metrics.differing(a, b) for a, b in zip(np.broadcast_to(r, tests.shape), tests)], axis=0
        )
        got = batched._differing_any(r, tests)
        assert got.dtype == bool and np.array_equal(got, want)
        assert want.sum() == (2 if r is ref else 3)


@pytest.mark.parametrize("backend", ["numpy", "llvm"][: len(BACKENDS)])
def test_a_case_measures_the_same_on_one_thread_as_on_several(backend, cache, monkeypatch):
    """study.measure.workers: the columns' threads change no value (every column, every map, bit for bit), and
    several threads really ran (a pool thread made a row)."""
    from study.measure import groups, workers

    scene = scene_from_dict(small_scene_dict())
    ms = [registry.make(n) for n in ("classical", "proxy_box", "linear_secant", "layered")]
    monkeypatch.setenv("STUDY_THREADS", "1")
    one = run_case(scene, ms, backend=backend, cache=cache)
    made_on = []
    row_of = groups.row_of

    def spy(ctx):
        made_on.append(threading.current_thread().name)
        return row_of(ctx)

    monkeypatch.setattr("study.measure.case.row_of", spy)
    monkeypatch.setenv("STUDY_THREADS", "4")
    monkeypatch.setattr(workers, "_pool", None)  # a pool of 4
    many = run_case(scene, ms, backend=backend, cache=cache)
    assert any(n.startswith("study-columns") for n in made_on), made_on
    assert len(one.rows) == len(many.rows) == len(ms) + 2
    for a, b in zip(one.rows, many.rows):
        assert list(a) == list(b)
        bad = [k for k in a if k not in ("seconds", "case_seconds") and not _close(a[k], b[k], 0.0, 0.0)]
        assert not bad, [(k, a[k], b[k]) for k in bad]
    for kind in ("images", "angle_maps", "outcome_maps", "flip_maps"):
        for label, m in getattr(one, kind).items():
            np.testing.assert_array_equal(getattr(many, kind)[label], m)


def test_a_stack_measures_each_image_as_alone_in_any_part(monkeypatch):
    """The columns' threads cut a case's stack into parts (batched._chunked): an image's every column has the same
    bits in a part of 1 as in a part of 6. Boolean indexing lays a stack's masked pixels out pixel-major, and a mean
    over such a strided image once summed in another order (one unit in the last place in 13 of fig4's 216 rows,
    1 against 16 threads)."""
    from study.measure import workers
    from study.measure.truth import Truth

    rng = np.random.default_rng(3)
    n = 160
    yy, xx = np.mgrid[:n, :n]
    mask = (yy - 80) ** 2 + (xx - 76) ** 2 < 60**2  # ≈ 11,000 pixels: long enough sums to round differently
    truth = rng.random((n, n, 3)).astype(np.float32)
    noise = rng.normal(0, 0.02, (n, n, 3)).astype(np.float32)
    r = SimpleNamespace(truth=Truth(truth, noise, np.zeros((1, 3)), noise, ev=0.0), mitsuba=truth + noise,
                        oracle=truth + 0.01, oracle_seed=truth + 0.02, oracle_coarse=truth, held_px=xx < 120,
                        on_held=mask & (xx < 120), mask=mask, sigma=0.02, against=())  # fmt: skip
    imgs = np.stack([truth + rng.normal(0, 0.1 * (i + 1), (n, n, 3)) for i in range(6)]).astype(np.float32)
    got = {}
    for threads in ("1", "6"):
        monkeypatch.setenv("STUDY_THREADS", threads)
        monkeypatch.setattr(workers, "_pool", None)
        got[threads] = batched.method_columns(imgs, r, backend="numpy", intervals=False)[0]
    for a, b in zip(got["1"], got["6"]):
        bad = [k for k in a if not _close(a[k], b[k], 0.0, 0.0)]
        assert not bad, [(k, a[k], b[k]) for k in bad]
