"""Caustic maps: photon power against a quadrature over the sphere's cone, localized photon hits against Embree in
an exact (analytic) impostor, the uv map against Embree, and energy conservation of the splatting."""

import math

import numpy as np
import pytest
from conftest import BACKENDS, run_cli, small_scene_dict

from study import backend as backends
from study import methods
from study.caustics import lightmap
from study.caustics import photons as caustics
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.reference.embree import Tracer
from study.scene import scene_from_dict

GLASS = {
    "shape": "sphere",
    "center": [0.6, 1.2, 0.3],
    "radius": 0.4,
    "material": {"type": "dielectric", "ior": 1.3},
}


@pytest.fixture(scope="module")
def scene():
    return scene_from_dict(small_scene_dict(object=GLASS))


@pytest.fixture(scope="module")
def tracer(scene):
    return Tracer(scene.mesh())


def _exact_env(scene, res, B):
    o = np.asarray(scene.reference.point)
    return EnvMap(
        analytic.box_impostor(res, np.asarray(scene.room.min) - o, np.asarray(scene.room.max) - o), B
    )


def test_frustum_solid_angles_sum_to_pyramid(scene):
    """The texels' exact solid angles add up to the square pyramid's 4·asin(sin²α') with tan α' the half width."""
    _, dw, a = caustics.frustum(scene, 37)
    half = math.atan(a)
    assert dw.sum() == pytest.approx(4 * math.asin(math.sin(half) ** 2), rel=1e-12)


@pytest.mark.parametrize("res", [64, 128])
def test_photon_power_matches_cone_quadrature(scene, tracer, res):
    """Σ photon power = I ∫_cone T dω (independent 1-D quadrature over the off-axis angle) within 1 %."""
    cm = caustics.exact_caustic_map(scene, tracer, res=res)
    np.testing.assert_allclose(cm.power.sum(0), caustics.cone_power(scene), rtol=0.01)
    assert 0.5 < cm.valid.mean() < 0.85  # the sphere's disc covers ~π/4 of the square


@pytest.mark.parametrize("bname", BACKENDS)
def test_localized_hits_equal_exact_within_a_texel(scene, tracer, bname):
    """In the exact box impostor, localized (10 iterations) photon hits fall within one cube texel (seen from the
    reference point) of Embree's hits, and land on the same surface for ≥ 99 % of photons."""
    B = backends.get(bname)
    res = 128
    uvm = lightmap.UVMap(lightmap.uv_map_texels(scene, res, tracer), B)
    cm = caustics.build_caustic_map(
        scene, methods.make("localized", iterations=10), _exact_env(scene, res, B), uvm, res=48
    )
    ex = caustics.exact_caustic_map(scene, tracer, res=48)
    both = cm.valid & ex.valid
    assert both.sum() > 0.95 * ex.valid.sum()
    o = np.asarray(scene.reference.point)
    ang = analytic.angle_deg(cm.shown[both] - o, ex.shown[both] - o)
    assert np.percentile(ang, 99) < 90 / res
    assert (cm.surface[both] == ex.surface[both]).mean() >= 0.99


def test_uv_map_agrees_with_embree(scene, tracer):
    """uv-map lookups in random directions give Embree's surface id (≥ 99 %) and (u, v) within 1.5 texels."""
    res = 64
    B = backends.get("numpy")
    uvm = lightmap.UVMap(lightmap.uv_map_texels(scene, res, tracer), B)
    _, d = analytic.random_rays(3000, extent=0, seed=5)
    sid, u, v = uvm.lookup(B.vec(d))
    o = np.broadcast_to(np.asarray(scene.reference.point, float), d.shape)
    hit = tracer.intersect(o, d)
    same = np.rint(sid).astype(int) == hit["surface"]
    assert same.mean() >= 0.99
    err = np.abs(np.stack([u, v], -1)[same] - hit["uv"][same]).max(-1)
    # one texel subtends ≤ 90°/R from the reference point; at ≥ 1.5 m from a 3–4 m wall that is < 2/R in uv
    assert np.percentile(err, 99) < 1.5 * 2 / res


def test_splat_conserves_power(scene):
    """Σ E · texel area over the light maps equals Σ photon power (also for photons near a surface edge)."""
    frames = lightmap.SurfaceFrames.of(scene.mesh())
    rng = np.random.default_rng(3)
    n = 500
    sid = rng.integers(0, 6, n)
    uv = rng.uniform(0, 1, (n, 2))
    power = rng.uniform(0, 1, (n, 3))
    E = lightmap.splat(sid, uv, power, frames, res=64, sigma=0.05)
    area = (frames.size_u * frames.size_v / 64**2)[:, None, None, None]
    np.testing.assert_allclose((E * area).sum((0, 1, 2)), power.sum(0), rtol=1e-9)


SMALL_CAUSTICS = """
methods = [{ name = "localized", iterations = [0, 10] }]
resolutions = [16, 32]

[scene]
room = { min = [-2.0, 0.0, -2.0], max = [2.0, 3.0, 2.0] }
light = { position = [0.3, 2.6, -0.4], intensity = [7.0, 7.0, 7.0] }
reference = { point = [0.0, 1.5, 0.0] }
object = { center = [0.6, 1.2, 0.3], radius = 0.4, material = { type = "MATERIAL" } }
camera = { eye = [-0.6, 1.9, -1.5], target = [0.8, 0.3, 0.8], fov = 60.0, width = 32, height = 32 }
render = { cube_res = 32, cube_spp = 2, spp = 2, max_depth = 3, supersample = 1 }

[caustic]
cube_res = 64
lightmap_res = 64
sigma = 0.05

[mitsuba]
spp = 16
"""


def test_caustics_sweep_cli_end_to_end(tmp_path):
    """`study caustics-sweep` on a tiny config writes fig8.png, sweep.csv and sweep.png; 10 iterations place the
    light map closer to exact photon tracing than 0 iterations; a mirror object is one 'error:' line, exit 2."""

    from study.tables import read_csv

    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_CAUSTICS.replace('"MATERIAL"', '"dielectric", ior = 1.3'))
    r = run_cli(
        *[
            "caustics-sweep",
            "--config",
            str(cfg),
            "--out",
            str(tmp_path / "o"),
            "--cache",
            str(tmp_path / "cache"),
        ],
    )
    assert r.exit_code == 0, r.output
    for f in ("fig8.png", "sweep/results.csv", "sweep.png", "fig8.csv"):
        assert (tmp_path / "o" / f).is_file()
    rows = [x for x in read_csv(tmp_path / "o" / "sweep" / "results.csv") if x["method"] == "localized"]
    assert len(rows) == 4
    for res in (16, 32):
        it = {x["knob_value"]: x for x in rows if x["caustic_res"] == res}
        assert it[10.0]["lm_rmse"] < it[0.0]["lm_rmse"]
    cfg.write_text(SMALL_CAUSTICS.replace("MATERIAL", "mirror"))
    r = run_cli("caustics-sweep", "--config", str(cfg), "--out", str(tmp_path / "o2"))
    assert r.exit_code == 2 and "error:" in r.output and "object.material" in r.output


# ---------------------------------------------------------------------------------------------- fig8's display
def test_knn_sigma_on_a_square_grid(scene):
    """Photons on a square grid of spacing h (one surface): the 8th neighbour of an inner photon is at h√2, so
    σ = h√2·√(π/8) = h√π/2; a denser grid is clipped to the config's σ, a lone photon gets σ_max."""
    from study.caustics import display

    frames = lightmap.SurfaceFrames.of(scene.mesh())
    s = 0  # grid in metres → uv of surface 0
    h = 0.04
    g = np.arange(10) * h + 0.5
    xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    uv = xy / np.array([frames.size_u[s], frames.size_v[s]])
    sig = display.knn_sigma(np.full(len(uv), s), uv, frames, sigma=0.001, k=8, sigma_max=1.0)
    inner = np.all((xy > g[1] - 1e-9) & (xy < g[-2] + 1e-9), -1)
    np.testing.assert_allclose(sig[inner], h * np.sqrt(np.pi) / 2, rtol=1e-9)
    assert np.all(sig[~inner] >= h * np.sqrt(np.pi) / 2 - 1e-12)
    assert np.all(display.knn_sigma(np.full(len(uv), s), uv, frames, sigma=0.1, k=8, sigma_max=1.0) == 0.1)
    lone = display.knn_sigma(np.array([s, -1]), np.array([[0.5, 0.5], [np.nan, np.nan]]), frames, sigma=0.01)
    assert lone[0] == display.SIGMA_MAX and np.isnan(lone[1])


def test_adaptive_splat_conserves_power_and_matches_fixed_where_dense(scene, tracer):
    """kNN splats move no power (Σ E·area = Σ photon power, as the fixed splat); where every photon's σ is the
    config's σ (a σ floor above every spacing) they are exactly the fixed-σ light maps."""
    from study.caustics import display

    frames = lightmap.SurfaceFrames.of(scene.mesh())
    cm = caustics.exact_caustic_map(scene, tracer, res=48)
    area = (frames.size_u * frames.size_v / 128**2)[:, None, None, None]
    E = display.splat_adaptive(cm, frames, res=128, sigma=0.02)  # 3σ > half a texel: no photon is lost
    np.testing.assert_allclose((E * area).sum((0, 1, 2)), cm.power.sum(0), rtol=1e-9)
    fixed = lightmap.splat(cm.surface, cm.uv, cm.power, frames, res=128, sigma=display.SIGMA_MAX)
    wide = display.splat_adaptive(cm, frames, res=128, sigma=display.SIGMA_MAX)
    np.testing.assert_allclose(wide, fixed, rtol=1e-9, atol=1e-12)
    assert not np.allclose(E, fixed)  # … and narrower where photons are dense


def test_direct_light_matches_mitsuba_direct(scene, tracer, tmp_path):
    """Ours, the direct part of fig8's image (point light, shadow rays, albedo/π), against Mitsuba's ``direct``
    render of the same room with the sphere made black (:func:`display.mitsuba_indirect` renders it): the images
    agree within 2 % on the room's pixels; the baked indirect light is ≥ 0 and lifts the sphere's shadow."""
    from study.cache import Cache
    from study.caustics import display
    from study.caustics.study import Receivers, direct_irradiance, radiance

    sc = scene.with_updates(
        {
            "camera.eye": [-0.6, 1.9, -1.5],
            "camera.target": [0.8, 0.3, 0.8],
            "camera.fov": 60.0,
            "render.supersample": 2,
        }
    )
    rec = Receivers(sc, tracer)
    ours = rec.image(radiance(lightmap.albedo_maps(sc.mesh()), rec, direct_irradiance(sc, tracer, rec)))
    cache = Cache(tmp_path)
    indirect = display.mitsuba_indirect(sc, 4, cache, spp=64)
    r = display.mitsuba_display(sc, 4, cache, spp=64)  # cached by the line above
    path, direct = r["path"], r["direct"]
    np.testing.assert_allclose(indirect, np.maximum(path - direct, 0))
    m = rec.diffuse_px
    assert abs(ours[m].mean() / direct[m].mean() - 1) < 0.02
    assert np.sqrt(np.mean((ours - direct)[m] ** 2)) < 0.1 * direct[m].mean()
    assert indirect.min() >= 0 and indirect[m].mean() > 0.05 * direct[m].mean()
    shadow = m & (ours.mean(-1) < 1e-6)  # the sphere's shadow: no direct light
    assert shadow.sum() > 5 and (indirect[shadow].mean(-1) > 0).all()
