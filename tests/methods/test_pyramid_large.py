"""The min pyramid past 2²⁴ texels (a stack of 512² probes: 7 × 6 × 512² texels and their levels): its reads are
exact where a float32 index would round (the main sweep's 512² cases stopped on an index out of bounds)."""

import numpy as np

from study.impostor.pyramid import MinPyramid


def test_the_last_faces_of_a_stack_past_2_24_texels_read_their_own_texels(B):
    R, faces = 512, 6 * 11  # 17.3 M texels at level 0: the deeper levels' offsets and indices pass 2²⁴
    dist = np.full((faces, R, R), 5.0, np.float32)
    dist[-1, 301, 77] = 1.0  # one near texel on the last face
    pyr = MinPyramid(dist, B)
    assert pyr.levels_at > 1 << 24
    face = np.array([faces - 1, faces - 1, faces - 2], np.float32)
    u = (np.array([77.5, 10.5, 77.5], np.float32)) / R  # the texel's centre; another texel; another face
    v = (np.array([301.5, 10.5, 301.5], np.float32)) / R
    f, uu, vv = (B.array(a) for a in (face, u, v))
    got = B.numpy(pyr.bound(f, uu, vv, f, uu, vv))
    from study.impostor.pyramid import MARGIN

    np.testing.assert_allclose(got, np.array([1.0, 5.0, 5.0]) * (1 - MARGIN), rtol=1e-6)
    # a span across the face reads a coarse level, whose texel holds the near one's minimum
    f, lo, hi = B.array(face[:1]), B.array(np.float32([0.01])), B.array(np.float32([0.99]))
    wide = B.numpy(pyr.bound(f, lo, lo, f, hi, hi))
    np.testing.assert_allclose(wide, [1.0 * (1 - MARGIN)], rtol=1e-6)
