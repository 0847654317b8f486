"""proxy_box and proxy_sphere on analytic environments (study.impostor.analytic): exact where the environment
is the proxy."""

import numpy as np
import pytest
from conftest import BOX_HI, BOX_LO

from study import backend as backends
from study import methods
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured
from study.methods.proxy_sphere import fibonacci_directions

O = np.array([0.0, 1.5, 0.0])  # the reference point, world


@pytest.fixture(scope="module")
def box_tex():
    return analytic.box_impostor(256, BOX_LO, BOX_HI)


def _trace(m, B, tex, x, d, info=None):
    tr = m.trace(B, Captured(impostor=EnvMap(tex, B), **(info or {})), B.vec(x), B.vec(d))
    return B.to_numpy(tr.l).astype(float), B.to_numpy(tr.shown).astype(float), B.numpy(tr.valid).astype(bool)


@pytest.mark.parametrize(
    "info",
    [None, {"reference": O, "room": (O + BOX_LO, O + BOX_HI)}],
    ids=["fitted-to-impostor", "room-from-info"],
)
def test_proxy_box_is_exact_when_the_proxy_is_the_room(box_tex, info, B):
    """Proxy = the room (from Captured.room, or fitted to the impostor's axis distances): the lookup direction is the
    exact hit's direction to float32 precision (≤ 1e-3°), and the shown point is off only by the bilinear
    interpolation of distance (texel precision: p99 < 0.02°), for origins anywhere up to 1.2 m from o."""
    x, d = analytic.random_rays(20_000, extent=1.2, seed=10)
    l, shown, valid = _trace(methods.make("proxy_box"), B, box_tex, x, d, info)
    exact = analytic.box_hit(x, d, BOX_LO, BOX_HI)
    assert valid.all()
    assert analytic.angle_deg(l, exact).max() < 1e-3
    ang = analytic.angle_deg(shown - x, exact - x)
    assert np.percentile(ang, 99) < 0.02 and ang.max() < 0.2


def test_proxy_box_from_params_and_outside_origins(box_tex):
    """A proxy given in world coordinates that is not the room: errors grow (median > 1°); origins outside the
    proxy are invalid (NaN shown point)."""
    B = backends.get("numpy")
    x, d = analytic.random_rays(5000, extent=1.2, seed=11)
    m = methods.make("proxy_box", box_min=(-1.0, 0.5, -1.0), box_max=(1.0, 2.5, 1.0))
    _, shown, valid = _trace(m, B, box_tex, x, d, {"reference": O})
    inside = np.all(np.abs(x) <= 1.0, axis=1)
    np.testing.assert_array_equal(valid, inside)
    assert np.isnan(shown[~valid]).all()
    exact = analytic.box_hit(x, d, BOX_LO, BOX_HI)
    assert np.median(analytic.angle_deg(shown[valid] - x[valid], exact[valid] - x[valid])) > 1.0


def test_proxy_sphere_is_exact_in_a_spherical_room(B):
    """The environment is a sphere of radius 2.5 around c = o + (0.3, −0.2, 0.1) seen from o; proxy_sphere with
    that sphere shows the exact ray–sphere hit (p99 < 0.05°, texel precision of the 128² map)."""
    rho, c = 2.5, np.array([0.3, -0.2, 0.1])
    dirs = analytic.cubemap.texel_directions(128).reshape(-1, 3)
    b = -(dirs @ c)  # rays from o (x = 0): L = −c
    t = -b + np.sqrt(b * b - (c @ c - rho**2))
    tex = np.concatenate([np.abs(dirs), t[:, None]], -1).reshape(6, 128, 128, 4).astype(np.float32)
    x, d = analytic.random_rays(20_000, extent=1.0, seed=12)
    m = methods.make("proxy_sphere", center=tuple(O + c), radius=rho)
    _, shown, valid = _trace(m, B, tex, x, d, {"reference": O})
    L = x - c
    bb = (L * d).sum(1)
    exact = x + d * (-bb + np.sqrt(bb * bb - ((L * L).sum(1) - rho**2)))[:, None]
    assert valid.all()
    ang = analytic.angle_deg(shown - x, exact - x)
    assert np.percentile(ang, 99) < 0.05


def test_proxy_sphere_fit_is_the_mean_room_distance(box_tex):
    """The fitted radius (mean distance from o to the room over directions) is the same whether the room comes
    from env.info or from the impostor (≤ 0.5 %), and lies between the nearest (1.5 m) and farthest (3.2 m)
    wall points."""
    from study.methods.proxy_sphere import fitted_radius

    B = backends.get("numpy")
    a = fitted_radius(B, EnvMap(box_tex, B))
    b = fitted_radius(B, Captured(impostor=EnvMap(box_tex, B), reference=O, room=(O + BOX_LO, O + BOX_HI)))
    assert abs(a - b) / b < 0.005 and 1.5 < b < 3.2
    w = fibonacci_directions(1000)
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0)
    assert np.abs(w.mean(0)).max() < 0.01  # evenly spread


def test_lookups_per_ray_of_the_new_methods():
    assert methods.make("proxy_box").lookups_per_ray() == 1
    assert methods.make("proxy_sphere").lookups_per_ray() == 1
    # before any search: the bound at max_steps (the march's length follows the cube resolution it meets)
    texel = {"hierarchical": False}  # the texel march: every sample read once
    assert (
        methods.make("linear_secant", max_steps=100, secant_steps=2, **texel).lookups_per_ray()
        == 1 + 100 + 2 + 1
    )
    # per layer g(0) and the march; the secant steps and the shown point on the kept layer alone
    assert methods.make("layered", layers=3, iterations=10, max_steps=100, **texel).lookups_per_ray() == (
        3 * (1 + 100) + 10 + 1
    )
    # the hierarchical march: at worst a failed pyramid read before each sample, and the bracket's start re-read
    from study.methods.march import iterations

    assert iterations(100) >= 2 * 100
    assert methods.make("linear_secant", max_steps=100, secant_steps=2).lookups_per_ray() == (
        1 + iterations(100) + 1 + 2 + 1
    )
