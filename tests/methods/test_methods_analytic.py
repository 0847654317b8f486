"""Every registered method on the analytic box room (exact distances, exact ray–box hits).

Each case states its expected outcome; the expected values come from study.impostor.analytic, not from the methods.
"""

import numpy as np
import pytest
from conftest import BACKENDS, BOX_HI, BOX_LO

from study import backend as backends
from study import methods
from study.errors import StudyError
from study.impostor import analytic
from study.impostor.envmap import EnvMap

RES = 256


@pytest.fixture(scope="module")
def box_tex():
    return analytic.box_impostor(RES, BOX_LO, BOX_HI)


def _shown(method, B, tex, x, d):
    env = EnvMap(tex, B)
    tr = method.trace(B, env, B.vec(x), B.vec(d))
    return B.to_numpy(tr.shown).astype(float), tr


def _angles(x, d, shown):
    exact = analytic.box_hit(x, d, BOX_LO, BOX_HI)
    return analytic.angle_deg(shown - x, exact - x)


@pytest.mark.parametrize("backend", BACKENDS)
def test_localized_10_iterations_median_below_005_deg(box_tex, backend):
    """localized(iterations=10), 256² cube, origins up to 0.8 m from the reference point: median ≤ 0.05°."""
    B = backends.get(backend)
    x, d = analytic.random_rays(50_000, extent=0.8, seed=0)
    shown, _ = _shown(methods.make("localized", iterations=10), B, box_tex, x, d)
    ang = _angles(x, d, shown)
    assert np.median(ang) <= 0.05
    assert np.percentile(ang, 95) <= 0.5
    assert np.all(np.isfinite(ang))


def test_localized_error_falls_with_iterations(box_tex):
    """Median error strictly falls from 0 to 1 to 3 iterations and does not rise to 10; classical is worst."""
    B = backends.get("numpy")
    x, d = analytic.random_rays(20_000, extent=0.8, seed=1)
    med = [
        np.median(_angles(x, d, _shown(methods.make("localized", iterations=n), B, box_tex, x, d)[0]))
        for n in (0, 1, 3, 10)
    ]
    classical = np.median(_angles(x, d, _shown(methods.make("classical"), B, box_tex, x, d)[0]))
    assert classical > med[0] > med[1] > med[2] >= med[3]


@pytest.mark.parametrize("name", methods.names())
def test_rays_from_the_reference_point_are_exact(box_tex, name, B):
    """x = o: the lookup direction is R itself, so every method shows the texel-exact hit (classical exactly)."""
    x = np.zeros((5000, 3))
    _, d = analytic.random_rays(5000, extent=0, seed=2)
    shown, _ = _shown(methods.make(name), B, box_tex, x, d)
    ang = _angles(x, d, shown)
    # the only error left is the bilinear interpolation of distance between texel centres
    assert np.percentile(ang, 99) < 0.02 and ang.max() < 0.2


@pytest.mark.parametrize("name", methods.names())
def test_constant_radiance_room_matches_reference(name, B):
    """Radiance 0.7 everywhere: whatever point a method localizes, it reads 0.7 (as do the oracle and the
    ray tracer) — for every valid ray."""
    tex = analytic.box_impostor(32, BOX_LO, BOX_HI, radiance=lambda p: np.full_like(p, 0.7))
    x, d = analytic.random_rays(5000, extent=1.0, seed=3)
    _, tr = _shown(methods.make(name), B, tex, x, d)
    rad = B.to_numpy(tr.radiance)
    valid = B.numpy(tr.valid).astype(bool)
    assert valid.mean() > 0.99
    np.testing.assert_allclose(rad[valid], 0.7, rtol=1e-6)


@pytest.mark.skipif(len(BACKENDS) < 2, reason="needs Dr.Jit's LLVM backend")
@pytest.mark.parametrize("name", methods.names())
def test_numpy_and_drjit_agree(box_tex, name):
    """The same method code on numpy and on Dr.Jit LLVM: shown points agree to 1e-4 relative (≥ 99.9 % of rays;
    the rest are rays whose bracketing decision flips on a float32 rounding difference)."""
    x, d = analytic.random_rays(20_000, extent=0.8, seed=4)
    m = methods.make(name)
    a, _ = _shown(m, backends.get("numpy"), box_tex, x, d)
    b, _ = _shown(m, backends.get("llvm"), box_tex, x, d)
    rel = np.linalg.norm(a - b, axis=1) / np.linalg.norm(a, axis=1)
    assert np.mean(rel <= 1e-4) >= 0.999
    assert np.median(rel) <= 1e-6


def test_unknown_method_and_parameter_are_errors():
    with pytest.raises(StudyError, match="classical.*localized|localized.*classical"):
        methods.make("nope")
    with pytest.raises(StudyError, match="method.iters.*iterations"):
        methods.make("localized", iters=3)
    with pytest.raises(StudyError, match="method.iterations"):
        methods.make("localized", iterations=-1)


def test_lookups_per_ray():
    assert methods.make("classical").lookups_per_ray() == 1
    assert methods.make("localized", iterations=10).lookups_per_ray() == 13
