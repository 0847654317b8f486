"""scripts/block_variance.py's O(pixels) lag-window sum against the FFT's: the squared block sums over every
placement give the lag sums weighted by the separable flat-top window, on random masked fields."""

import runpy
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from study.stats import region

BLOCKS = runpy.run_path(str(Path(__file__).resolve().parents[2] / "scripts" / "block_variance.py"))


@pytest.mark.parametrize("seed", range(4))
def test_block_sums_are_the_fft_lag_sums_under_the_separable_window(seed):
    rng = np.random.default_rng(seed)
    shape = tuple(rng.integers(8, 50, 2))
    mask = ndimage.gaussian_filter(rng.normal(size=shape), 2) > -0.3
    reg = region.region(mask)
    e = np.where(mask, ndimage.gaussian_filter(rng.normal(size=(2, *shape)), (0, 2, 2)), 0.0)[
        :, reg.box[0], reg.box[1]
    ]
    my, mx = (int(v) for v in rng.integers(1, 6, 2))
    R = reg.reach
    dy, dx = np.mgrid[-R : R + 1, -R : R + 1]
    w = np.clip(2 - np.abs(dy) / my, 0, 1) * np.clip(2 - np.abs(dx) / mx, 0, 1)
    assert 2 * max(my, mx) <= R  # the window lies inside the FFT's exact lags
    want = (reg.centred_sums(e) * w).sum(axis=(1, 2))
    np.testing.assert_allclose(BLOCKS["window_sum"](e, my, mx), want, rtol=1e-10)
