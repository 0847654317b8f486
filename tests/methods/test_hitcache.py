"""The hit-lighting cache (study/impostor/hitcache.py): a world-space grid of radiance, six normal bins per cell,
filled from surface samples and read at a hit — against analytic radiance fields and Mitsuba's own radiance."""

import numpy as np
import pytest

from study.impostor import hitcache as H

BOX = (np.zeros(3), np.full(3, 4.0))  # a 4 m cube


def _floor_points(n, seed):
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.uniform(0, 4, n), np.zeros(n), rng.uniform(0, 4, n)])
    return p, np.tile([0.0, 1.0, 0.0], (n, 1))


def test_cached_linear_field_errs_by_half_a_cell_and_halves_with_the_cell():
    """L(p) = 0.1·x on the floor: a cell's mean is L at its centre, so a read errs by at most |∇L|·h/2 and its
    RMS by |∇L|·h/√12 (uniform offset within the cell); doubling the resolution halves it."""
    p, n = _floor_points(200_000, 0)
    q, qn = _floor_points(5_000, 1)
    L = lambda x: np.repeat(0.1 * x[:, :1], 3, axis=1)  # noqa: E731
    errs = []
    for res in (8, 16, 32):
        c = H.GridCache.empty(*BOX, res)
        c.add(p, n, L(p))
        got, miss = c.query(q, qn)
        assert not miss.any()
        e = got - L(q)
        h = 4.0 / res
        assert np.abs(e).max() <= 0.1 * h / 2 * 1.2  # + the cell mean's sampling error (~1/√3000 of the cell)
        rms = float(np.sqrt(np.mean(e**2)))
        assert rms == pytest.approx(0.1 * h / np.sqrt(12), rel=0.1)
        errs.append(rms)
    assert errs[0] / errs[1] == pytest.approx(2, rel=0.1) and errs[1] / errs[2] == pytest.approx(2, rel=0.15)


def test_normal_bins_keep_a_corners_two_walls_apart():
    """Floor (L = 1) and the wall x = 0 (L = 5) share the corner's cells; each face reads its own value."""
    floor = np.array([[0.05, 0.0, 1.0]]), np.array([[0.0, 1.0, 0.0]])
    wall = np.array([[0.0, 0.05, 1.0]]), np.array([[1.0, 0.0, 0.0]])
    c = H.GridCache.empty(*BOX, 4)
    c.add(*floor, np.ones((1, 3)))
    c.add(*wall, np.full((1, 3), 5.0))
    assert c.query(*floor)[0][0, 0] == 1.0 and c.query(*wall)[0][0, 0] == 5.0
    assert H.normal_bin(np.array([[0.0, -1, 0], [0.2, 0.1, -0.9]])).tolist() == [3, 5]


def test_a_cell_no_sample_reached_is_a_counted_miss_read_as_its_bins_mean():
    c = H.GridCache.empty(*BOX, 4)
    c.add(
        np.array([[0.5, 0, 0.5], [1.5, 0, 0.5]]),
        np.tile([0, 1.0, 0], (2, 1)),
        np.array([[1.0] * 3, [3.0] * 3]),
    )
    got, miss = c.query(np.array([[3.5, 0, 3.5], [0.5, 0, 0.5]]), np.tile([0, 1.0, 0], (2, 1)))
    assert miss.tolist() == [True, False] and got[:, 0].tolist() == [2.0, 1.0]


def test_surface_samples_spread_by_area_on_both_sides():
    """Two triangles of areas 1 and 3: a quarter of the points on the first (within 4σ), every point on its
    triangle's plane, half of the normals flipped."""
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 1], [3, 0, 1], [0, 2, 1]], float)
    F = np.array([[0, 1, 2], [3, 4, 5]])
    p, n = H.surface_samples(V, F, 40_000, seed=3)
    first = np.mean(p[:40_000, 2] == 0)
    assert abs(first - 0.25) < 4 * np.sqrt(0.25 * 0.75 / 40_000)
    assert np.all((p[:, 0] / np.where(p[:, 2] == 0, 1, 3) + p[:, 1] / 2) <= 1 + 1e-9)
    np.testing.assert_allclose(n[:40_000], -n[40_000:])


def test_hit_normals_face_the_ray():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1]], float)  # winding normal −y
    d = np.array([[0, -1.0, 0], [0, 1.0, 0], [1.0, 0, 0]])
    n = H.hit_normals(V, np.array([[0, 1, 2]]), np.array([0, 0, -1]), d)
    np.testing.assert_allclose(n[:2], [[0, 1, 0], [0, -1, 0]])
    assert np.isnan(n[2]).all()


def test_filled_from_mitsuba_the_cache_converges_to_the_radiance_at_the_hit():
    """The small room: rays from its centre to the walls; the cache read at each exact hit approaches Mitsuba's
    radiance along the ray as the cells shrink (the error at 4 cells per side is larger than at 16)."""
    from study.reference import mitsuba as mref
    from study.reference.embree import Tracer
    from study.scene import room_mesh, scene_from_dict
    from tests.conftest import small_scene_dict

    scene = scene_from_dict(small_scene_dict())
    mesh = room_mesh(scene)
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    rng = np.random.default_rng(5)
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.tile((lo + hi) / 2, (len(d), 1))
    hit = Tracer(mesh).intersect(o, d)
    ok = hit["prim"] >= 0
    truth = mref.radiance_along(scene, o[ok], d[ok], spp=64, seed=1)
    nrm = H.hit_normals(mesh.vertices, mesh.faces, hit["prim"][ok], d[ok])
    rms = {}
    for res in (4, 16):
        c = H.fill(
            H.GridCache.empty(lo, hi, res), scene, mesh.vertices, mesh.faces, samples=30_000, spp=16, seed=2
        )
        got, miss = c.query(hit["point"][ok], nrm)
        assert miss.mean() < 0.02
        rms[res] = float(np.sqrt(np.mean((got - truth) ** 2)))
    assert rms[16] < rms[4]
