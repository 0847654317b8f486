"""Exact references against analytic answers: Embree hits, captured distances, EXR storage, the cache."""

import numpy as np
import pytest
from conftest import small_scene_dict

from study.cache import Cache
from study.cache import flush as cache_flush
from study.errors import StudyError
from study.impostor import analytic
from study.impostor.capture import Impostor, capture_distance, read_exr, write_exr
from study.reference.embree import Tracer
from study.scene import scene_from_dict


@pytest.fixture(scope="module")
def scene():
    return scene_from_dict(small_scene_dict())


def test_embree_hits_equal_analytic_ray_box_hits(scene):
    o = np.array(scene.reference.point)
    x, d = analytic.random_rays(20_000, extent=0.9, seed=5)
    x = x + o
    hit = Tracer(scene.mesh()).intersect(x, d)
    exact = analytic.box_hit(x, d, scene.room.min, scene.room.max)
    assert np.all(hit["prim"] >= 0)
    np.testing.assert_allclose(hit["point"], exact, atol=2e-5)


def test_embree_reports_surface_and_uv(scene):
    """A ray straight down from (x, 1, z) hits the floor at uv = ((z − zmin)/4, (x − xmin)/4)."""
    o = np.array([[0.5, 1.0, -1.0]])
    hit = Tracer(scene.mesh()).intersect(o, np.array([[0.0, -1.0, 0.0]]))
    assert scene.mesh().surfaces[hit["surface"][0]] == "floor"
    np.testing.assert_allclose(hit["uv"][0], [1.0 / 4, 2.5 / 4], atol=1e-6)


def test_captured_distances_equal_analytic_distances(scene):
    res = 24
    dist = capture_distance(scene, res)
    o = np.array(scene.reference.point)
    lo, hi = np.array(scene.room.min) - o, np.array(scene.room.max) - o
    exact = analytic.box_impostor(res, lo, hi)[..., 3]
    np.testing.assert_allclose(dist, exact, rtol=1e-5)


def test_impostor_exr_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(6)
    imp = Impostor(
        np.array([0.1, 1.5, -0.2]),
        rng.uniform(0, 3, (6, 8, 8, 3)).astype(np.float32),
        rng.uniform(0.5, 3, (6, 8, 8)).astype(np.float32),
    )
    imp.save(tmp_path / "imp.exr")
    back = Impostor.load(tmp_path / "imp.exr")
    np.testing.assert_array_equal(back.texels(), imp.texels())
    np.testing.assert_array_equal(back.reference, imp.reference)
    assert (tmp_path / "imp.exr").read_bytes()[:4] == b"v/1\x01"  # an OpenEXR file, not a TIFF


def test_impostor_of_wrong_shape_or_damaged_is_an_error(tmp_path):
    imp = Impostor(np.zeros(3), np.ones((6, 8, 8, 3), np.float32), np.ones((6, 8, 8), np.float32))
    imp.save(tmp_path / "imp.exr")
    write_exr(tmp_path / "imp.exr", np.ones((40, 8, 4), np.float32))  # wrong shape
    with pytest.raises(StudyError, match="imp.exr: impostor EXR has shape"):
        Impostor.load(tmp_path / "imp.exr")
    (tmp_path / "imp.exr").write_bytes(b"garbage")
    with pytest.raises(StudyError, match="imp.exr: unreadable EXR"):
        Impostor.load(tmp_path / "imp.exr")


def test_cache_recomputes_damaged_entries(tmp_path):
    cache = Cache(tmp_path)
    calls = []

    def make():
        calls.append(1)
        return np.arange(24, dtype=np.float32).reshape(2, 3, 4)

    a = cache.get("k", "key1", make, code=make)
    b = cache.get("k", "key1", make, code=make)
    assert len(calls) == 1 and np.array_equal(a, b)
    cache_flush()  # the entry on disk (written off this thread)
    arr = next((tmp_path / "k").glob("*.npy"))
    data = bytearray(arr.read_bytes())
    data[-8:] = b"\xff" * 8  # flip the last values' bytes
    arr.write_bytes(bytes(data))
    c = cache.get("k", "key1", make, code=make)
    assert len(calls) == 2 and np.array_equal(c, a)
    cache_flush()  # the recomputed entry on disk before the next damage
    arr.write_bytes(b"")  # truncated to nothing
    cache.get("k", "key1", make, code=make)
    assert len(calls) == 3
    cache_flush()
    # an entry of the format before issue 15 (float32 EXR beside the JSON) is read, with the same checks
    arr.unlink()
    write_exr(arr.with_suffix(".exr"), a.reshape(-1, 3, 4))
    d = cache.get("k", "key1", make, code=make)
    assert len(calls) == 3 and np.array_equal(d, a)
    write_exr(arr.with_suffix(".exr"), a.reshape(-1, 3, 4) + 1)  # another array: its checksum fails
    cache.get("k", "key1", make, code=make)
    cache_flush()
    assert len(calls) == 4 and arr.exists()


def test_exr_helpers_round_trip(tmp_path):
    a = np.random.default_rng(7).normal(size=(5, 7, 3)).astype(np.float32)
    write_exr(tmp_path / "a.exr", a)
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr"), a)
