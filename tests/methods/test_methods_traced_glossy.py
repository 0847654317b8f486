"""``traced_glossy``, the exact query for rough objects: K lobe rays traced and shaded exactly per secondary ray.

Provenance: an analytic distant environment (radiance a smooth function of direction alone, handed over as the
exact shading), the lobe's average per (n, v) by brute-force quadrature over a Fibonacci sphere of directions with
the GGX BRDF written out here (D, Smith's separable G, no Fresnel) — independent of :mod:`study.impostor.ggx`'s
sampler and weights, so a biased sampler shows as an error that stops falling with K.

Tolerance of the 1/√K law: the method is the self-normalized estimator, consistent, not unbiased: its MSE is
σ²/K + O(1/K²) (at K = 1 it is L along one sampled direction, whatever its weight). Measured here over 3 seeds
(8 pairs × 300 rays × 3 channels), RMSE·√K = 0.44 at K = 1, 0.61 at 4, 0.67–0.70 at 16, 0.70–0.72 at 64, 256 and
1024: the law holds from K = 16 on, within 7 %. The RMSE's own relative spread over 7200 values is ≈ √(κ − 1)/(2√n)
≲ 2 % (κ ≤ 10 the errors' kurtosis). Tolerance 12 % on RMSE(16)/RMSE(256) = 4 and 10 % on RMSE(64)/RMSE(256) = 2:
wide of both, narrow of the planted biases (a lobe 1.5× too wide, the weights dropped), whose error stops falling:
RMSE(16)/RMSE(256) below 3.5.
"""

import numpy as np
import pytest

from study import backend as backends
from study import methods
from study.harness.config import expand_methods
from study.impostor import analytic, ggx
from study.impostor.envmap import EnvMap
from study.impostor.views import Captured, Lobe

LO, HI = np.array([-2.0, -1.5, -2.0]), np.array([2.0, 1.5, 2.0])
ALPHA = 0.3
PAIRS, REPEAT = 8, 300
B = backends.get("numpy")


def env_radiance(d):
    """A distant environment: radiance by direction alone, smooth with a strong gradient (positive)."""
    d = np.asarray(d, float)
    return np.stack(
        [1.0 + 0.9 * d[:, 0], 1.0 + 0.6 * d[:, 1] + 0.8 * d[:, 2] ** 2, np.exp(1.5 * d[:, 2])], -1
    )


def pairs(seed=5):
    """(n, v) pairs: normals uniform, v in the normal's hemisphere (n·v ≥ 0.3)."""
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(PAIRS, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v = rng.normal(size=(PAIRS, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v = np.where((np.sum(n * v, 1) < 0)[:, None], v - 2 * np.sum(n * v, 1)[:, None] * n, v)
    v = v + n * np.maximum(0.0, 0.3 - np.sum(n * v, 1))[:, None]
    return n, v / np.linalg.norm(v, axis=1, keepdims=True)


def quadrature_truth(n, v, alpha, points=400_000):
    """∫ L f (n·l) dl / ∫ f (n·l) dl per pair, on a Fibonacci sphere (uniform solid angle), f = D G₁G₁/(4 n·l n·v)."""
    i = np.arange(points) + 0.5
    z = 1 - 2 * i / points
    phi = np.pi * (1 + 5**0.5) * i
    s = np.sqrt(1 - z * z)
    l = np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)
    L = env_radiance(l)
    a2 = alpha * alpha
    out = []
    for nn, vv in zip(n, v):
        nl, nv = l @ nn, float(nn @ vv)
        h = l + vv
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        nh = h @ nn
        D = a2 / (np.pi * (nh * nh * (a2 - 1) + 1) ** 2)

        def g1(c):
            return 2 * c / (c + np.sqrt(a2 + (1 - a2) * c * c))

        w = np.where((nl > 0) & (h @ vv > 0), D * g1(nv) * g1(np.maximum(nl, 1e-9)) / (4 * nv), 0.0)
        out.append((L * w[:, None]).sum(0) / w.sum())
    return np.array(out)


@pytest.fixture(scope="module")
def setup():
    n, v = pairs()
    truth = quadrature_truth(n, v, ALPHA)
    N, V = np.repeat(n, REPEAT, 0), np.repeat(v, REPEAT, 0)
    R = 2 * np.sum(N * V, 1)[:, None] * N - V  # the mirror direction of v about n
    x = np.zeros_like(R) + np.array([0.1, -0.2, 0.3])
    env = Captured(
        impostor=EnvMap(analytic.box_impostor(16, LO, HI), B),
        hits=lambda o, d: o + d * analytic.box_hit_t(o, d, LO, HI)[:, None],
        shade=lambda o, d: env_radiance(d),
        lobe=Lobe(ALPHA, B.vec(N)),
        reference=(0.0, 0.0, 0.0),
    )
    return env, x, R, np.repeat(truth, REPEAT, 0)


def rmse(K, setup, seed=0):
    env, x, R, truth = setup
    tr = methods.make("traced_glossy", samples=K, seed=seed).trace(
        B, env, B.vec(x), B.vec(R), check_origin=False
    )
    rad = B.to_numpy(tr.radiance).astype(float)
    return float(np.sqrt(np.mean((rad - truth) ** 2))), rad, tr


def test_error_falls_as_one_over_root_k(setup):
    e = {K: rmse(K, setup)[0] for K in (16, 64, 256)}
    assert 4 * 0.88 < e[16] / e[256] < 4 * 1.12, e
    assert 2 * 0.9 < e[64] / e[256] < 2 * 1.1, e


def test_its_shown_point_is_the_exact_hit_and_lookups_are_k(setup):
    env, x, R, _ = setup
    _, rad, tr = rmse(4, setup)
    want = x + R * analytic.box_hit_t(x, R, LO, HI)[:, None]
    assert np.allclose(B.to_numpy(tr.shown), want, atol=1e-4) and np.isfinite(rad).all()
    assert np.all(B.numpy(tr.lookups) == 4) and methods.make("traced_glossy", samples=4).queries == 4


def _biased_half_vectors(alpha, u1, u2):
    return REAL_HALF_VECTORS(min(1.0, alpha * 1.5), u1, u2)  # a lobe 1.5× too wide


REAL_HALF_VECTORS = ggx.half_vectors


@pytest.mark.parametrize("plant", ["wide sampler", "no weights"])
def test_a_biased_lobe_sampler_is_caught(setup, monkeypatch, plant):
    if plant == "wide sampler":
        monkeypatch.setattr(ggx, "half_vectors", _biased_half_vectors)
    else:
        real = ggx.lobe_directions
        monkeypatch.setattr(ggx, "lobe_directions", lambda *a: (real(*a)[0], real(*a)[1] * 0 + 1.0))
    e16, e256 = rmse(16, setup)[0], rmse(256, setup)[0]
    assert e16 / e256 < 4 * 0.88, (plant, e16, e256)  # the bias stays: the error stops falling as 1/√K


def test_it_is_a_glossy_method_priced_at_k_queries():
    assert "traced_glossy(samples=4)" in [m.label for m in methods.glossy_methods()]
    assert "traced_glossy" not in [m.name for m in methods.all_methods()]
    labels = [
        m.label
        for m in expand_methods(["glossy", {"name": "traced_glossy", "samples": [1, 16]}], source="test")
    ]
    assert {"traced_glossy(samples=1)", "traced_glossy(samples=16)"} <= set(labels)


def _write(path, rows):
    import csv

    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def test_study_pareto_prices_it_at_k_exact_queries_on_a_glossy_table(tmp_path):
    """A glossy table with traced_glossy at K = 1, 4, 16 and a stand-in the bench has no row for: the K rungs are
    placed at K × the exact query's time (the bench's ray_intersect_preliminary row) and form the front.
    Planted: priced at one query each, K = 1 and 4 would not be on the front (K = 16 dominates them)."""
    from study.report import pareto

    d = tmp_path / "reports" / "fig_glossy"
    d.mkdir(parents=True)
    errs = {"traced_glossy(samples=1)": 0.4, "traced_glossy(samples=4)": 0.2, "traced_glossy(samples=16)": 0.1,
            "prefiltered": 0.3}  # fmt: skip
    rows = [{"case": f"c{c}", "method": lab.split("(")[0], "label": lab, "family": lab.split("(")[0],
             "cube_res": 64, "rmse_truth_debiased": e} for c in range(3) for lab, e in errs.items()]  # fmt: skip
    _write(d / "metrics.csv", rows)
    batch = "fig4 close-up (1, 1, 1) 1024²"
    bench = [{"batch": batch, "backend": "cuda", "path": "frozen", "label": "classical", "ms_per_frame": 0.05,
              "kernel_ms_per_frame": 0.02}]  # fmt: skip
    bench += [{"batch": batch, "backend": "cuda", "path": q, "label": "exact: Mitsuba cuda_ad_rgb", "ms_per_frame": ms,
               "kernel_ms_per_frame": ms / 4} for q, ms in (("ray_intersect", 1.8), ("ray_intersect_preliminary", 0.2),
                                                            ("ray_test", 0.1))]  # fmt: skip
    gpu = tmp_path / "bench-gpu.csv"
    _write(gpu, bench)
    gpu.with_suffix(".md").write_text(
        "# study bench (gpu)\n\nmachine: Test CPU, 2 cores; GPU: NVIDIA Testcard, 1.0, 10 MiB\n\ncode: abc\n"
    )
    times = pareto.device_times(gpu, clock="wall")
    scale = 1920 * 1080 / 1024**2
    for k in (1, 4, 16):
        assert times.ms[f"traced_glossy(samples={k})"] == pytest.approx(0.2 * k * scale)
    assert times.ms["traced"] == pytest.approx(0.2 * scale)
    pareto.write_pareto(tmp_path / "reports", tmp_path / "out", [gpu], metric="rmse_truth_debiased")
    md = (tmp_path / "out" / "pareto.md").read_text().split("## fig_glossy")[1]
    line = {r.split("|")[1].strip(): r for r in md.splitlines() if r.startswith("| ")}
    assert all("◆" in line[f"traced_glossy(samples={k})"] for k in (1, 4, 16))
    assert "prefiltered" in md.split("Not benched")[1]
