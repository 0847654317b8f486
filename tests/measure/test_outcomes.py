"""Per-ray outcome classes (study.measure.outcomes), the acceptance test of issue 17: a ray whose exact hit (a
column top) is hidden from the reference point, on which ``localized`` shows a point of the very same ray at the
wrong depth — angle ≈ 0, class WRONG_DEPTH. Exact answers come from an analytic room with one column, not from the
methods."""

import numpy as np
import pytest
from conftest import BACKENDS, BOX_HI, BOX_LO

from study import backend as backends
from study import methods
from study.impostor import analytic, cubemap
from study.impostor.envmap import EnvMap
from study.measure import metrics, outcomes
from study.measure.outcomes import CORRECT, NO_HIT, WRONG_DEPTH, WRONG_SURFACE

RES = 256
#: fig5's column (footprint 0.6 m at (−0.9, −0.9), 1.7 m tall) relative to the reference point (1.5 m above the
#: floor): its top, 0.2 m above o, is hidden from o.
COL_LO, COL_HI = np.array([-1.2, -1.5, -1.2]), np.array([-0.6, 0.2, -0.6])


def _column_t(o, d):
    """Where rays o + t d enter the column box (t > 0), else inf."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (COL_LO - o) / d, (COL_HI - o) / d
    near, far = np.nanmax(np.minimum(t1, t2), -1), np.nanmin(np.maximum(t1, t2), -1)
    return np.where((near <= far) & (near > 0), near, np.inf)


def _hit(o, d):
    """Exact first hits in the room with the column: (N, 3)."""
    t = np.minimum(analytic.box_hit_t(o, d, BOX_LO, BOX_HI), _column_t(o, d))
    return o + d * t[:, None]


@pytest.fixture(scope="module")
def column_env():
    """The room with the column seen from o = 0: exact distances along texel-centre directions."""
    dirs = cubemap.texel_directions(RES).reshape(-1, 3)
    dist = np.linalg.norm(_hit(np.zeros_like(dirs), dirs), axis=-1)
    tex = np.concatenate([np.abs(dirs), dist[:, None]], -1).reshape(6, RES, RES, 4).astype(np.float32)
    return EnvMap(tex, backends.get("numpy"))


def _hidden(exact):
    d = exact / np.linalg.norm(exact, axis=-1, keepdims=True)
    return np.linalg.norm(_hit(np.zeros_like(d), d), axis=-1) < np.linalg.norm(exact, axis=-1) - 1e-6


def _localized(env, x, R):
    B = env.B
    tr = methods.make("localized", iterations=10).trace(B, env, B.vec(x), B.vec(R))
    return B.to_numpy(tr.shown).astype(float)


def test_hidden_column_top_is_wrong_depth_with_tiny_angle(column_env):
    """Issue 17: straight down from above the column onto its top (hidden from o). localized converges on the
    silhouette of the column's edge, a point of the same ray 10 cm above the top: the angle at x is < 0.1°, yet
    the class is WRONG_DEPTH. A ray onto a visible wall, from the same scene, is CORRECT."""
    x = np.array([[-0.9, 0.6, -0.9], [0.5, 0.3, 0.2]])
    R = np.array([[0.0, -1.0, 0.0], [0.3, -0.2, 0.9]])
    R /= np.linalg.norm(R, axis=1, keepdims=True)
    exact = _hit(x, R)
    np.testing.assert_allclose(exact[0], [-0.9, 0.2, -0.9])
    assert list(_hidden(exact)) == [True, False]
    shown = _localized(column_env, x, R)
    oc = outcomes.classify(x, R, shown, exact, eps=outcomes.tolerance(np.zeros(3), exact, RES))
    ang = metrics.angular_error(x, shown, exact)
    assert ang[0] < 0.1 and oc.dist[0] > 0.05  # the angle is blind, the distance is not
    assert list(oc.cls) == [WRONG_DEPTH, CORRECT]
    assert abs(oc.depth_error[0]) > 0.05 and abs(oc.depth_error[1]) < 0.01


def test_no_hit_wrong_surface_and_the_ray_line():
    """NaN shown → NO_HIT; on the ray beyond ε → WRONG_DEPTH (either side of the hit), behind the origin or off the
    line → WRONG_SURFACE; within ε of the hit → CORRECT whatever the direction."""
    x = np.zeros((6, 3))
    R = np.tile([0.0, 0.0, 1.0], (6, 1))
    exact = np.tile([0.0, 0.0, 2.0], (6, 1))
    shown = np.array([[np.nan] * 3, [0, 0, 3.0], [0, 0, 1.0], [0, 0, -1.0], [0.5, 0, 2.0], [0.005, 0, 2.005]])
    oc = outcomes.classify(x, R, shown, exact, eps=0.01)
    assert list(oc.cls) == [NO_HIT, WRONG_DEPTH, WRONG_DEPTH, WRONG_SURFACE, WRONG_SURFACE, CORRECT]
    np.testing.assert_allclose(oc.depth_error[1:4], [1.0, -1.0, -3.0])
    assert np.isnan(oc.dist[0]) and np.isnan(oc.depth_error[0])


def test_exact_origin_defines_the_exact_ray():
    """With ``exact_origin`` (dielectrics), the line is the exact ray through the exact hit, not (x, R)."""
    x, R = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    exact = np.array([[1.0, 0.0, 2.0]])
    shown = np.array([[1.0, 0.0, 3.0]])  # on the exact ray from (1, 0, 0), not on (x, R)
    assert outcomes.classify(x, R, shown, exact, eps=0.01).cls[0] == WRONG_SURFACE
    oc = outcomes.classify(x, R, shown, exact, eps=0.01, exact_origin=np.array([[1.0, 0.0, 0.0]]))
    assert oc.cls[0] == WRONG_DEPTH and oc.depth_error[0] == pytest.approx(1.0)


def mixed_rays(with_origin, far=False):
    """Rays in the analytic box with shown points near the hit, on the ray, off it and missing (and, with ``far``,
    exact hits and shown points at infinity for a quarter of them, as in an open environment)."""
    rng = np.random.default_rng(3)
    n = 400
    x, R = analytic.random_rays(n, extent=0.8, seed=4)
    exact = analytic.box_hit(x, R, BOX_LO, BOX_HI)
    t = np.sum((exact - x) * R, -1)
    kind = rng.integers(0, 4, n)  # near the hit, on the ray, off it, missing
    shown = np.where(
        (kind == 0)[:, None],
        exact + rng.normal(scale=0.01, size=(n, 3)),
        np.where(
            (kind == 1)[:, None],
            x + R * (t * rng.uniform(0.2, 1.5, n))[:, None] + rng.normal(scale=0.005, size=(n, 3)),
            exact + rng.normal(scale=0.5, size=(n, 3)),
        ),
    )
    shown[kind == 3] = np.nan
    if far:  # at infinity: exact, shown or both, along the ray or not
        k = rng.integers(0, 4, n)
        exact[k == 0] = x[k == 0] + R[k == 0] * cubemap.FAR
        shown[k == 1] = x[k == 1] + R[k == 1] * cubemap.FAR
        exact[k == 2] = x[k == 2] + R[k == 2] * cubemap.FAR
        shown[k == 2] = (
            x[k == 2] + (R[k == 2] + rng.normal(scale=0.002, size=(int((k == 2).sum()), 3))) * cubemap.FAR
        )
    eps = outcomes.tolerance(np.zeros(3), exact, 64)
    origin = x + rng.normal(scale=0.01, size=(n, 3)) if with_origin else None
    return x, R, shown, exact, eps, origin


@pytest.mark.parametrize("with_origin", [False, True])
def test_classify_agrees_with_its_ref_twin(with_origin):
    x, R, shown, exact, eps, origin = mixed_rays(with_origin)
    a = outcomes.classify(x, R, shown, exact, eps=eps, exact_origin=origin)
    b = outcomes.classify_ref(x, R, shown, exact, eps=eps, exact_origin=origin)
    assert set(np.unique(a.cls)) == {CORRECT, WRONG_DEPTH, WRONG_SURFACE, NO_HIT}
    np.testing.assert_array_equal(a.cls, b.cls)
    np.testing.assert_allclose(a.dist, b.dist, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(a.depth_error, b.depth_error, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("far", [False, True])
@pytest.mark.parametrize("with_origin", [False, True])
@pytest.mark.skipif("llvm" not in BACKENDS, reason="needs Dr.Jit's LLVM backend")
def test_the_device_classes_are_numpys(with_origin, far):
    """classify_on (one kernel on the backend, float64) gives classify's classes, distances and depth errors."""
    x, R, shown, exact, eps, origin = mixed_rays(with_origin, far)
    a = outcomes.classify(x, R, shown, exact, eps=eps, exact_origin=origin)
    b = outcomes.classify_on(backends.get("llvm"), x, R, shown, exact, eps=eps, exact_origin=origin)
    assert set(np.unique(a.cls)) == {CORRECT, WRONG_DEPTH, WRONG_SURFACE, NO_HIT}
    np.testing.assert_array_equal(a.cls, b.cls)
    np.testing.assert_allclose(a.dist, b.dist, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(a.depth_error, b.depth_error, rtol=1e-9, atol=1e-9)


def test_texel_footprint_is_the_gnomonic_texel_size():
    """At a face centre one texel is 2/res rad; elsewhere the footprint matches the angle between neighbouring
    texel centres (measured from cubemap.texel_directions), times the distance; ε never drops below 1 cm."""
    res = 64
    dirs = cubemap.texel_directions(res)
    face, i, j = 0, np.array([31, 5, 40]), np.array([31, 9, 2])
    fwd = outcomes.texel_footprint(np.zeros(3), 3.0 * dirs[face, i, j], res)
    across = np.degrees(np.arccos(np.clip(np.sum(dirs[face, i, j] * dirs[face, i, j + 1], -1), -1, 1)))
    down = np.degrees(np.arccos(np.clip(np.sum(dirs[face, i, j] * dirs[face, i + 1, j], -1), -1, 1)))
    np.testing.assert_allclose(fwd, 3.0 * np.radians(np.maximum(across, down)), rtol=0.05)
    assert outcomes.texel_footprint(np.zeros(3), np.array([[0.0, 0.0, 2.0]]), res)[0] == pytest.approx(
        4 / res
    )
    assert outcomes.tolerance(np.ones(3), np.array([[1.0, 1.0, 1.2]]), 1024)[0] == outcomes.EPS_FIXED


def test_outcome_columns_and_pixel_majority():
    cls = np.array([CORRECT, CORRECT, WRONG_DEPTH, NO_HIT, WRONG_SURFACE, CORRECT], np.int8)
    dist = np.array([0.0, 0.001, 0.5, np.nan, 1.0, 0.002])
    oc = outcomes.Outcomes(cls, dist, np.array([0.0, 0.001, -0.5, np.nan, 0.3, 0.0]), np.full(6, 0.01))
    hidden = np.array([False, False, True, True, False, False])
    col = outcomes.outcome_columns(oc, hidden, np.array([0.0, 0.01, 0.02, np.nan, 5.0, 0.0]))
    assert col["correct_fraction"] == 0.5 and col["wrong_fraction"] == 0.5
    assert (
        col["wrong_depth_fraction"]
        == col["no_hit_fraction"]
        == col["wrong_surface_fraction"]
        == pytest.approx(1 / 6)
    )
    assert col["wrong_fraction_hidden"] == 1.0 and col["wrong_fraction_visible"] == 0.25
    assert col["hidden_fraction"] == pytest.approx(1 / 3) and col["angle_p95_hidden_deg"] == pytest.approx(
        0.02
    )
    assert col["depth_error_p95"] == pytest.approx(np.percentile([0.0, 0.001, 0.5, 0.0], 95))
    none_hidden = outcomes.outcome_columns(oc, np.zeros(6, bool), np.zeros(6))
    assert np.isnan(none_hidden["wrong_fraction_hidden"]) and np.isnan(none_hidden["angle_p95_hidden_deg"])
    frac = np.array([[[0.5, 0.5, 0, 0], [0.75, 0, 0.25, 0], [np.nan] * 4]])  # a tie goes to the worse class
    np.testing.assert_array_equal(outcomes.majority(frac), [[WRONG_DEPTH, CORRECT, np.nan]])
