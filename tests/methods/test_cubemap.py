"""The cube-map convention: texel directions, direction → (face, u, v), bilinear lookup without face bleeding."""

import numpy as np
import pytest

from study import backend as backends
from study.impostor import cubemap
from study.impostor.envmap import EnvMap


@pytest.mark.parametrize("res", [1, 4, 33])
def test_texel_centres_map_to_their_own_texel(res):
    d = cubemap.texel_directions(res)
    B = backends.get("numpy")
    face, u, v = cubemap.face_uv(B, *(d[..., i].ravel() for i in range(3)))
    f_exp, i_exp, j_exp = np.meshgrid(np.arange(6), np.arange(res), np.arange(res), indexing="ij")
    assert np.array_equal(face.astype(int), f_exp.ravel())
    np.testing.assert_allclose(u * res - 0.5, j_exp.ravel(), atol=1e-4)
    np.testing.assert_allclose(v * res - 0.5, i_exp.ravel(), atol=1e-4)


def test_face_uv_inverse():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    B = backends.get("numpy")
    face, u, v = cubemap.face_uv(B, *d.T.astype(np.float32))
    back = cubemap.face_uv_to_direction(face.astype(int), u, v)
    np.testing.assert_allclose(back, d, atol=1e-5)


def test_faces_are_right_handed_cameras():
    """right = forward × up for every face (Mitsuba's look_at convention)."""
    for fwd, right, up in cubemap.FACES:
        np.testing.assert_array_equal(np.cross(fwd, up), right)


def test_lookup_matches_slow_reference_twin(B):
    rng = np.random.default_rng(2)
    tex = rng.uniform(size=(6, 16, 16, 4)).astype(np.float32)
    d = rng.normal(size=(20000, 3))
    env = EnvMap(tex, B)
    got = np.stack([B.numpy(c) for c in env.lookup(B.vec(d))], -1)
    ref = cubemap.lookup_ref(tex, d)
    np.testing.assert_allclose(got, ref, atol=5e-5 if B.name == "numpy" else 5e-4)


def test_lookup_never_bleeds_across_faces(B):
    """Each face holds its index as a constant: lookups anywhere, edges and corners included, return exactly
    the index of the face the direction belongs to."""
    res = 8
    tex = np.broadcast_to(np.arange(6, dtype=np.float32)[:, None, None, None], (6, res, res, 1)).copy()
    rng = np.random.default_rng(3)
    d = rng.normal(size=(4000, 3))
    d[:1000, 0] = d[:1000, 1]  # on the x/y edges
    d[1000:1100] = np.sign(d[1000:1100])  # corners
    env = EnvMap(tex, B)
    got = B.numpy(env.lookup(B.vec(d))[0])
    face, _, _ = cubemap.face_uv(backends.get("numpy"), *d.T.astype(np.float32))
    np.testing.assert_allclose(got, face, atol=1e-5)


def test_numpy_bilinear_sample_matches_scipy_map_coordinates():
    """The numpy backend's texture sample (flat-index gathers) is scipy's order-1 interpolation with clamped
    edges at texel centres (u·R − ½, v·R − ½), on every face, including the last row and column and R = 1."""
    from scipy.ndimage import map_coordinates

    from study.backend import NumpyBackend

    B, rng = NumpyBackend(), np.random.default_rng(5)
    for R in (1, 2, 7):
        tex = B.texture(rng.uniform(size=(6, R, R, 2)))
        n = 500
        face = rng.integers(0, 6, n).astype(np.float32)
        u, v = (rng.uniform(-0.1, 1.1, n).astype(np.float32) for _ in range(2))
        got = np.stack(B.sample(tex, face, u, v), -1)
        ref = np.stack(
            [
                [
                    map_coordinates(
                        tex[int(f), :, :, c].astype(float),
                        [[vi * R - 0.5], [ui * R - 0.5]],
                        order=1,
                        mode="nearest",
                    )[0]
                    for f, ui, vi in zip(face, u, v)
                ]
                for c in range(2)
            ],
            -1,
        )
        np.testing.assert_allclose(got, ref, atol=1e-5)
