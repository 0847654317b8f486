"""Refraction and mesh objects against independent answers: Snell's law traced here by angles (not by
study.optics.interfaces' vector form), an analytic glass cube for total internal reflection, trimesh/Embree
for meshes, and
Mitsuba for the glass sphere's image."""

import numpy as np
import pytest

from study import backend as backends
from study import methods
from study.errors import StudyError
from study.impostor import analytic
from study.impostor.envmap import EnvMap
from study.optics import interfaces as optics
from study.optics import shading
from study.optics.distance_map import DistanceMap
from study.scene import objects, scene_from_dict
from tests.conftest import BOX_HI, BOX_LO, small_scene_dict

GLASS = {"type": "dielectric", "ior": 1.5}


def glass_scene(refraction="double", shape="sphere", ior=1.5, **render):
    d = small_scene_dict()
    d["object"] = {
        "shape": shape,
        "center": [0.6, 1.2, 0.3],
        "radius": 0.4,
        "rotation": [30.0, 20.0, 0.0],
        "material": {"type": "dielectric", "ior": ior},
    }
    d["render"].update(refraction=refraction, **render)
    return scene_from_dict(d)


# ---------------------------------------------------------------------------------------------- independent Snell
def snell_by_angles(d, n, eta):
    """Refraction written with angles in the plane of incidence: sin θt = η sin θi, t = −cos θt n + sin θt s,
    s the unit tangent of d. Independent of optics.refract's vector formula."""
    cos_i = -np.sum(d * n, axis=1)
    tang = d + cos_i[:, None] * n
    s = tang / np.linalg.norm(tang, axis=1, keepdims=True)
    theta_t = np.arcsin(eta * np.sqrt(1 - cos_i**2))
    return -np.cos(theta_t)[:, None] * n + np.sin(theta_t)[:, None] * s


def sphere_far_side(p, d, c, r):
    """Far root of |p + t d − c| = r by the quadratic formula."""
    L = p - c
    b, cc = np.sum(L * d, 1), np.sum(L * L, 1) - r * r
    return p + (-b + np.sqrt(b * b - cc))[:, None] * d


def test_double_refraction_through_sphere_matches_snell_trace_with_exact_environment():
    """Outgoing rays equal an angle-form two-interface trace (to 1e-9), and localized(iterations=40) on the
    analytic box impostor shows, seen from the exit point, the trace's exact box hit to ≤ 0.05° for every ray."""
    sc = glass_scene("double")
    rays = shading.object_rays(sc)
    M = int(rays.hit.sum())
    c, r, ior = np.array(sc.object.center), sc.object.radius, sc.object.material.ior
    # ----- the independent trace of the camera rays that hit
    x, V, N = rays.x[:M], rays.V[:M], rays.N[:M]
    inner = snell_by_angles(V, N, 1 / ior)
    e = sphere_far_side(x, inner, c, r)
    out = snell_by_angles(inner, -(e - c) / r, ior)
    kept = rays.src[M:]
    assert rays.stats["dropped_fraction"] == 0 and len(kept) == M
    np.testing.assert_allclose(rays.x[M:], e, atol=1e-9)
    np.testing.assert_allclose(rays.R[M:], out, atol=1e-9)
    # ----- the method on the exact environment: the box room around the reference point
    o = np.array(sc.reference.point)
    B = backends.get("numpy")
    env = EnvMap(analytic.box_impostor(512, BOX_LO, BOX_HI), B)
    tr = methods.make("localized", iterations=40).trace(B, env, B.vec(e - o), B.vec(out))
    shown = B.to_numpy(tr.shown).astype(float)
    exact = analytic.box_hit(e - o, out, BOX_LO, BOX_HI)
    ang = analytic.angle_deg(shown - (e - o), exact - (e - o))
    assert np.all(np.isfinite(ang)) and ang.max() <= 0.05, ang.max()


def test_single_refraction_looks_up_the_entry_refracted_ray():
    """Single refraction (the paper): the transmitted secondary ray starts at the entry point along the
    angle-form refracted direction, with weight 1 − F; reflected and transmitted weights sum to 1."""
    sc = glass_scene("single")
    rays = shading.object_rays(sc)
    M = int(rays.hit.sum())
    np.testing.assert_allclose(rays.x[M:], rays.x[:M], atol=0)
    np.testing.assert_allclose(rays.R[M:], snell_by_angles(rays.V[:M], rays.N[:M], 1 / 1.5), atol=1e-9)
    np.testing.assert_allclose(rays.weight[:M, 0] + rays.weight[M:, 0], 1.0, atol=1e-12)


# ---------------------------------------------------------------------------------------------- total
# internal reflection
def cube_exit(half=0.5):
    """Exact exit from the cube [−half, half]³ and its outward face normal."""

    def exit_fn(p, d):
        e = analytic.box_hit(p, d, [-half] * 3, [half] * 3)
        k = np.argmax(np.abs(e) / half, axis=1)
        n = np.zeros_like(e)
        n[np.arange(len(e)), k] = np.sign(e[np.arange(len(e)), k])
        return e, n, np.ones(len(p), bool)

    return exit_fn


def test_glass_cube_total_internal_reflection_is_followed_then_dropped():
    """A ray entering a glass cube's top at 60° meets the side face at 55° > 41.8° (critical angle of n = 1.5):
    one total internal reflection, then it leaves through the bottom parallel to its incoming direction with the
    side-axis component flipped. With no bounce allowed it is dropped: NaN origin, ok False, transmittance 0."""
    th = np.radians(60)
    d = np.array([[np.sin(th), -np.cos(th), 0.0]])
    x = np.array([[0.3, 0.5, 0.0]])  # on the top face, close to the +x side
    N = np.array([[0.0, 1.0, 0.0]])
    p = optics.through_object(x, d, N, 1.5, cube_exit(), max_bounces=4)
    assert p.ok.all() and p.bounces[0] == 1
    np.testing.assert_allclose(p.out[0], [-np.sin(th), -np.cos(th), 0.0], atol=1e-12)
    assert p.origin[0, 1] == pytest.approx(-0.5) and 0 < p.transmittance[0] < 1
    q = optics.through_object(x, d, N, 1.5, cube_exit(), max_bounces=0)
    assert not q.ok[0] and np.isnan(q.origin).all() and q.transmittance[0] == 0


def test_tir_in_a_diamond_blob_reaches_no_nan_into_metrics():
    """A high-index (2.4) blob has many TIR paths; they are followed (tir_fraction > 0), the ones left inside are
    dropped and counted, and every secondary ray handed on is finite, also the exact ones."""
    for bounces in (0, 4):
        rays = shading.object_rays(glass_scene("double", shape="blob", ior=2.4, internal_bounces=bounces))
        ex, eR = rays.exact_rays()
        for a in (rays.x, rays.R, rays.weight, ex, eR):
            assert np.isfinite(a).all()
        if bounces == 0:
            dropped0 = rays.stats["dropped_fraction"]
        else:
            assert rays.stats["tir_fraction"] > 0.05
            assert rays.stats["dropped_fraction"] < dropped0


# ---------------------------------------------------------------------------------------------- meshes
@pytest.mark.parametrize("shape", ["torus", "knot", "blob"])
def test_mesh_normals_are_smooth_and_outward(shape):
    """Closed, consistently wound meshes; points 1% of the bounding radius along each vertex normal lie outside
    (trimesh.contains), against it inside; normals of the two ends of every edge differ by < 25°."""
    m = objects.unit_shape(shape, 3)
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0
    n = np.asarray(m.vertex_normals)
    rng = np.random.default_rng(1)
    idx = rng.choice(len(m.vertices), 400, replace=False)
    v = m.vertices[idx]
    assert not m.contains(v + 0.01 * n[idx]).any()
    assert m.contains(v - 0.01 * n[idx]).all()
    e = m.edges_unique
    cos = np.sum(n[e[:, 0]] * n[e[:, 1]], axis=1)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 25


def test_mesh_hits_have_interpolated_normals_facing_the_camera():
    """Camera rays on a torus: Embree hit points lie within 1e-4 of the bounding sphere; the interpolated
    normals face the incoming ray and stay within 10° of the triangle's geometric normal."""
    sc = glass_scene(shape="torus")
    g = objects.object_geometry(sc)
    from study.scene import camera_rays

    o, d = camera_rays(sc.camera, 1)
    h = g.hits(o.reshape(-1, 3), d.reshape(-1, 3))
    hit = np.isfinite(h["t"])
    assert hit.sum() > 20
    p = o.reshape(-1, 3)[hit] + d.reshape(-1, 3)[hit] * h["t"][hit, None]
    assert np.linalg.norm(p - g.center, axis=1).max() <= g.radius + 1e-4
    assert (np.sum(h["normal"][hit] * d.reshape(-1, 3)[hit], 1) < 0).all()
    cos = np.sum(h["normal"][hit] * h["geometric"][hit], 1)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 10


def test_mesh_placement_uses_the_bounding_sphere():
    """A torus whose bounding sphere reaches a column or a wall is refused; unknown shapes name the allowed."""
    d = small_scene_dict(columns=[{"center": [1.2, 0.3], "footprint": [0.4, 0.4], "height": 2.0}])
    d["object"] = {"shape": "torus", "center": [0.6, 1.2, 0.3], "radius": 0.45, "material": GLASS}
    with pytest.raises(StudyError, match="object.center: the torus .*overlaps columns"):
        scene_from_dict(d)
    d["object"].update(center=[1.7, 1.2, 0.0], radius=0.4)
    with pytest.raises(StudyError, match="inside the room"):
        scene_from_dict(small_scene_dict(object=d["object"]))
    with pytest.raises(StudyError, match="object.shape.*'sphere', 'torus', 'knot' or 'blob'"):
        scene_from_dict(small_scene_dict(object={"shape": "cube", "material": GLASS}))


def test_distance_map_exit_of_a_sphere_is_close_to_the_closed_form():
    """The object's own distance map searched from inside finds a sphere's far side (where the map is exact up
    to interpolation) within 1 mm for a 0.4 m sphere at face resolution 128, for rays refracted in at the
    surface (random incoming directions, n = 1.5: inside within 41.8° of the inward normal)."""
    sc = glass_scene()
    g = objects.object_geometry(sc)
    dm = DistanceMap(g, 128)
    rng = np.random.default_rng(3)
    nrm = rng.normal(size=(500, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    x = g.center + g.radius * nrm
    d = rng.normal(size=nrm.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.where(np.sum(d * nrm, 1, keepdims=True) < 0, d, -d)
    d = snell_by_angles(d, nrm, 1 / 1.5)
    e_map, n_map, ok = dm.exit(x, d)
    e_ref, _, _ = g.exit(x, d)
    assert ok.all()
    assert np.linalg.norm(e_map - e_ref, axis=1).max() < 1e-3


# ---------------------------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def glass_cases(tmp_path_factory):
    from study.cache import Cache
    from study.measure.case import run_case

    cache = Cache(tmp_path_factory.mktemp("cache"))
    ms = [methods.make("classical"), methods.make("localized", iterations=10)]
    kw = dict(
        camera={"eye": [-0.3, 1.7, -1.9], "target": [0.6, 1.2, 0.3], "fov": 30.0, "width": 48, "height": 48}
    )
    out = {}
    for mode in ("single", "double"):
        d = small_scene_dict(**kw)
        d["object"]["material"] = GLASS
        d["render"].update(refraction=mode, spp=32, cube_res=64, cube_spp=16)
        out[mode] = run_case(scene_from_dict(d), ms, cache=cache)
    return out


def test_glass_sphere_end_to_end(glass_cases):
    """Every row of a refractive sphere case is finite; localized(10) is within 0.05° median and 0.01 RMSE of
    the oracle; Mitsuba's image is closer to the oracle composite with double refraction than with the paper's
    single refraction, its RMSE below 0.1 and its mean radiance over the sphere within 10%."""
    for mode, case in glass_cases.items():
        by = {r["label"]: r for r in case.rows}
        for r in case.rows:
            assert np.isfinite(r["angle_median_deg"]) and np.isfinite(r["rmse_mitsuba"]), (mode, r["label"])
        assert by["localized(iterations=10)"]["angle_median_deg"] < 0.05
        assert by["localized(iterations=10)"]["rmse_oracle"] < 0.01
        assert by["classical"]["angle_median_deg"] > 1
    dbl, sgl = glass_cases["double"], glass_cases["single"]
    e_dbl = {r["label"]: r for r in dbl.rows}["oracle_map"]["rmse_mitsuba"]
    e_sgl = {r["label"]: r for r in sgl.rows}["oracle_map"]["rmse_mitsuba"]
    m = dbl.mask
    print(
        f"\nglass sphere 48²: oracle vs Mitsuba RMSE double {e_dbl:.4f}, single {e_sgl:.4f}; "
        f"mean radiance ratio oracle/Mitsuba {dbl.oracle[m].mean() / dbl.mitsuba[m].mean():.4f}"
    )
    assert e_dbl < e_sgl and e_dbl < 0.1, (e_dbl, e_sgl)
    assert abs(dbl.oracle[m].mean() / dbl.mitsuba[m].mean() - 1) < 0.1


def test_mitsuba_gets_the_same_triangles_and_normals():
    """Camera rays against Mitsuba's mesh of a rotated torus (room included) and against the object's Embree
    scene: the same rays hit the object, at the same distance (1e-4 m) with the same shading normal (0.5°)."""
    from study.reference.mitsuba import mi, scene_dict
    from study.reference.mitsuba import sensor as _sensor
    from study.scene import camera_rays

    m = mi()
    sc = glass_scene(shape="torus")
    c = sc.camera
    sensor = _sensor(c.eye, c.target, c.up, c.fov, c.width, c.height, 1, 0)
    msc = m.load_dict(scene_dict(sc, with_object=True, sensor=sensor))
    o, d = (a.reshape(-1, 3) for a in camera_rays(c, 1))
    si = msc.ray_intersect(m.Ray3f(m.Point3f(*o.T.astype(np.float32)), m.Vector3f(*d.T.astype(np.float32))))
    g = objects.object_geometry(sc)
    h = g.hits(o, d)
    ours = np.isfinite(h["t"])
    t_m = np.array(si.t)
    theirs = np.isclose(t_m, h["t"], atol=1e-4)
    assert ours.sum() > 20 and np.array_equal(ours, theirs)
    n_m = np.stack([np.array(v) for v in (si.sh_frame.n.x, si.sh_frame.n.y, si.sh_frame.n.z)], -1)[ours]
    ang = np.degrees(np.arccos(np.clip(np.sum(n_m * h["normal"][ours], 1), -1, 1)))
    assert ang.max() < 0.5, ang.max()
