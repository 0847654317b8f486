"""Many short runs (study.measure.seeds, Celarek et al. 2019) and each reference's own noise beside the error it
debiases (study.measure.truth, Whittle et al. 2017), checked on simulations with known answers: E[MSE] and its
split into variance and squared bias; per-pixel Welch p-values uniform for two renders of one distribution and
piled at 0 for a planted bias (Kolmogorov–Smirnov keeps the one, rejects the other); a reference rendered with
few samples raises the noise flag, one with many does not; the frame's noise measure grows by √2 at half the
samples."""

import math

import numpy as np
import pytest

from study.measure import seeds, truth

SHAPE = (40, 40)


def _renders(rng, s, spp, bias=0.0, base=None):
    """s renders of a 'scene' whose pixels are the mean of ``spp`` exponential samples (heavy-tailed, as path
    tracing's): mean base + bias, per-pixel variance base² / spp."""
    base = np.full((*SHAPE, 3), 0.5) if base is None else base
    return np.stack([rng.exponential(base[None], (spp, *base.shape)).mean(0) + bias for _ in range(s)])


def test_e_mse_splits_into_variance_and_squared_bias():
    rng = np.random.default_rng(0)
    mask = np.ones(SHAPE, bool)
    ref = np.full((*SHAPE, 3), 0.5)
    runs = _renders(rng, 16, 8, bias=0.05)
    got = seeds.mse_over_seeds(runs, ref, mask)
    var = 0.25 / 8  # exponential: variance = mean²
    assert got["variance"] == pytest.approx(var, rel=0.05)
    assert got["bias2"] == pytest.approx(0.05**2, rel=0.15)
    assert got["mse_mean"] == pytest.approx(var + 0.05**2, rel=0.05)
    assert 0 < got["mse_var"] < (0.2 * got["mse_mean"]) ** 2  # 4800 values per MSE: it moves little
    own = seeds.mse_over_seeds(runs, None, mask)  # a reference's own noise: leave one out
    assert own["mse_mean"] == pytest.approx(var * (1 + 1 / 15), rel=0.05)


def test_welch_p_values_are_uniform_for_two_renders_of_one_distribution():
    rng = np.random.default_rng(1)
    mask = np.ones(SHAPE, bool)
    p = seeds.welch_map(_renders(rng, 12, 16), _renders(rng, 12, 16), mask)
    assert np.isfinite(p).all()
    assert seeds.uniformity(p) > 0.05
    assert abs(np.mean(p < 0.05) - 0.05) < 0.03


def test_a_planted_bias_piles_the_p_values_at_zero():
    rng = np.random.default_rng(2)
    mask = np.ones(SHAPE, bool)
    p = seeds.welch_map(_renders(rng, 12, 16), _renders(rng, 12, 16, bias=0.05), mask)
    assert seeds.uniformity(p) < 1e-6
    assert np.mean(p < 0.05) > 0.3


def test_welch_keeps_only_the_masked_pixels():
    rng = np.random.default_rng(3)
    mask = np.zeros(SHAPE, bool)
    mask[4:8, 4:8] = True
    p = seeds.welch_map(_renders(rng, 4, 4), _renders(rng, 4, 4), mask, tile=1)
    assert np.isfinite(p[mask]).all() and np.isnan(p[~mask]).all()
    mask[8, 4] = True  # a tile half in the mask is left out
    p = seeds.welch_map(_renders(rng, 4, 4), _renders(rng, 4, 4), mask)
    assert p.shape == (20, 20) and np.isfinite(p).sum() == 4
    assert math.isnan(seeds.uniformity(np.full(3, np.nan)))


def _case(rng, spp):
    """A method 0.05 off everywhere, measured against a reference of ``spp`` samples rendered at two seeds."""
    base = np.full((*SHAPE, 3), 0.5)
    a, b = _renders(rng, 2, spp, base=base)
    ref = truth.Truth(image=(a + b) / 2, noise=(a - b) / 2, along=np.zeros((1, 3)), mitsuba_noise=(a - b) / 2)
    return truth.columns(base + 0.05, ref, (a + b) / 2, mask=np.ones(SHAPE, bool))


def test_a_noisy_reference_raises_the_flag():
    rng = np.random.default_rng(4)
    few, many = _case(rng, 2), _case(rng, 4096)
    assert few["truth_noise_flag"] == 1.0 and few["mitsuba_noise_flag"] == 1.0, few
    assert many["truth_noise_flag"] == 0.0 and many["mitsuba_noise_flag"] == 0.0, many
    assert few["truth_noise_rmse"] > few["rmse_truth_debiased"] / 3  # the flag's own condition
    assert math.isnan(truth.noise_flag(math.nan, 0.1)) and math.isnan(truth.noise_flag(0.1, math.nan))


def test_the_frame_noise_grows_by_root_two_at_half_the_samples():
    rng = np.random.default_rng(5)
    full, half = (_case(rng, spp)["mitsuba_noise_frame"] for spp in (32, 16))
    assert half / full == pytest.approx(math.sqrt(2), rel=0.05)
