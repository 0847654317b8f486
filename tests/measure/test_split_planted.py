"""Planted errors land in their own term of the split (study/measure/split.py, each part from its own experiment).

A known room: a box of side 4 around the reference point o, its walls painted with a smooth analytic radiance L(p).
The impostor is its cube map (texel centres, 128²); rays leave o in random directions (one per pixel) and hit the
walls where the geometry says; the method reads the map at its shown point (bilinear, the case's own
:class:`~study.impostor.envmap.EnvMap`). The clean case — the search shows the exact hit, the views hold every hit,
the truth has no noise — has every part near 0. Then one error at a time:

* **shift the views**: the method reads the map 3° off the exact hit → only ``search``;
* **hide a wall**: o's map loses the +x wall behind an occluder (its face holds the occluder's radiance) and those
  hits are not held → only ``visibility``;
* **blur the impostor**: a 15 × 15 box blur of the map's texels, read by oracle and method alike → only
  ``representation_direct``;
* **add noise**: the truth's two seeds get noise → only ``noise``.

"Only" means every other part stays within its interval of its clean value; and in every case the parts meet the
total (``dec_sums_direct``). The last test says what the split *without* T (``dec_representation``: seed and
resolution) makes of the blur: it does not see it; the residual carries it.
"""

from __future__ import annotations

import numpy as np
import pytest

from study import backend as backends
from study.impostor import cubemap
from study.impostor.envmap import EnvMap
from study.measure import split

P, RES, HALF = 3000, 128, 2.0  # rays (pixels), map resolution, half the box's side
PARTS = ("search", "visibility", "representation_direct", "noise")


def radiance(p):
    """(N, 3) smooth analytic radiance of the wall point p (N, 3)."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    base = 0.5 + 0.25 * np.sin(3.0 * x + 0.4) * np.cos(2.5 * y) + 0.1 * z / HALF
    return np.stack([base, 0.9 * base + 0.05, 1.1 * base - 0.05], -1)


def box_hit(d):
    """The wall point o + t d of the box (o = 0)."""
    return d * (HALF / np.abs(d).max(-1))[:, None]


def capture(res=RES):
    """(6, R, R, 4) texels: the walls' radiance at each texel centre's hit, and its distance."""
    d = cubemap.texel_directions(res).reshape(-1, 3)
    p = box_hit(d)
    tex = np.concatenate([radiance(p), np.linalg.norm(p, axis=-1, keepdims=True)], -1)
    return tex.reshape(6, res, res, 4).astype(np.float32)


NB = backends.get("numpy")


def read(texels, v):
    """The map's colour towards v (N, 3) (EnvMap.lookup, bilinear)."""
    return np.stack([np.asarray(c, float) for c in EnvMap(texels, NB).lookup(NB.vec(v))[:3]], -1)


def rotate(v, deg):
    """v turned by ``deg`` about a fixed oblique axis."""
    k = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    a = np.radians(deg)
    return v * np.cos(a) + np.cross(k, v) * np.sin(a) + k * (v @ k)[:, None] * (1 - np.cos(a))


@pytest.fixture(scope="module")
def rays():
    d = np.random.default_rng(7).normal(size=(P, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return box_hit(d)


def split_of(hit, *, texels=None, shown=None, held=None, seeds=None):
    """The split's columns of one planted case: the oracle reads ``texels`` at the exact hit, the method at
    ``shown``; the truth is L(hit) (or two noisy seeds of it)."""
    texels = capture() if texels is None else texels
    O = read(texels, hit)
    img = read(texels, hit if shown is None else shown)
    T = radiance(hit)
    t1, t2 = (T, T) if seeds is None else seeds
    truth, noise = (t1 + t2) / 2, (t1 - t2) / 2
    held = np.ones(P, bool) if held is None else held
    O = np.where(held[:, None], O, np.nan)
    grid = (50, 60)  # P pixels as an image, for the pixel blocks of the bootstrap
    shape = lambda a: a.reshape(*grid, -1)  # noqa: E731
    return split.split_columns(*(shape(a) for a in (img, truth, noise, O, O, O)),
                               mask=np.ones(grid, bool), held_px=held.reshape(grid))  # fmt: skip


@pytest.fixture(scope="module")
def clean(rays):
    return split_of(rays)


def only(c, term, clean):
    """``term`` carries the error; every other part stays within its interval of its clean value; the parts meet
    the total."""
    assert c[f"dec_{term}"] > 20 * max(abs(clean[f"dec_{term}"]), 1e-7), (term, c[f"dec_{term}"])
    assert c[f"dec_{term}"] > 0.5 * c["dec_total"], (term, c[f"dec_{term}"], c["dec_total"])
    for k in PARTS:
        if k != term:
            lo, hi = c[f"dec_{k}_lo"], c[f"dec_{k}_hi"]
            width = max(hi - lo, 1e-12)
            assert abs(c[f"dec_{k}"] - clean[f"dec_{k}"]) <= width, (
                term,
                k,
                c[f"dec_{k}"],
                clean[f"dec_{k}"],
            )
    assert c["dec_sums_direct"] == 1, (term, c["dec_total"], [c[f"dec_{k}"] for k in PARTS])


def test_clean_case_is_near_zero(clean):
    assert clean["dec_search"] == 0 and clean["dec_visibility"] == 0 and clean["dec_noise"] == 0
    assert 0 <= clean["dec_representation_direct"] < 1e-5  # bilinear texels of a smooth radiance
    assert clean["dec_sums_direct"] == 1


def test_shifted_views_land_in_search(rays, clean):
    only(split_of(rays, shown=rotate(rays, 3.0)), "search", clean)


def test_a_hidden_wall_lands_in_visibility(rays, clean):
    tex = capture()
    tex[0, ..., :3] = 0.05  # face +x (the +x wall, the box being centred at o): an occluder's radiance
    hidden = rays[:, 0] >= HALF * (1 - 1e-9)  # hits on the +x wall: o no longer sees them
    assert 0.1 < hidden.mean() < 0.25
    c = split_of(rays, texels=tex, held=~hidden)
    only(c, "visibility", clean)
    assert c["unheld_pixels"] == hidden.sum()


def test_a_blurred_impostor_lands_in_representation(rays, clean):
    from scipy.ndimage import uniform_filter

    tex = capture()
    tex[..., :3] = uniform_filter(tex[..., :3], size=(1, 15, 15, 1), mode="nearest")  # each face on its own
    only(split_of(rays, texels=tex), "representation_direct", clean)


def test_noise_lands_in_noise(rays, clean):
    rng = np.random.default_rng(3)
    T = radiance(rays)
    seeds = (T + rng.normal(0, 0.05, T.shape), T + rng.normal(0, 0.05, T.shape))
    c = split_of(rays, seeds=seeds)
    only(c, "noise", clean)
    assert c["dec_noise"] == pytest.approx(0.05**2 / 2, rel=0.1)


def test_the_split_without_truth_misses_the_blur(rays, clean):
    """The seed-and-resolution representation (``dec_representation``, measured without T) cannot see a blur:
    the map is smooth, so its half-resolution twin agrees with it; the error the blur makes is left to the
    residual. The direct measurement (O against T) sees it."""
    from scipy.ndimage import uniform_filter

    tex = capture()
    tex[..., :3] = uniform_filter(tex[..., :3], size=(1, 15, 15, 1), mode="nearest")
    O = read(tex, rays)
    Oc = read(split.coarser(tex), rays)
    T = radiance(rays)
    grid = (50, 60)
    shape = lambda a: a.reshape(*grid, -1)  # noqa: E731
    c = split.split_columns(*(shape(a) for a in (O, T, 0 * T, O, O, Oc)), mask=np.ones(grid, bool),
                            held_px=np.ones(grid, bool))  # fmt: skip
    assert c["dec_representation"] < 0.2 * c["dec_representation_direct"]
    assert c["dec_residual_lo"] > 0  # the blur is in the residual
