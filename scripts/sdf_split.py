"""The distance field's error, split: representation (Mitsuba's exact trace of the grid vs Embree's exact hit on the
triangles) and tracing (sdf's sphere trace vs Mitsuba's exact trace of the same grid), with the build time, for
fig5's room and Mitsuba's Cornell box at 32³, 64³ and 128³. 3000 rays from inside each room's bounds (those whose
origin the field puts inside a solid dropped), uniform directions, seed 5. CPU only (about a minute on 2 cores):
``.venv/bin/python scripts/sdf_split.py``."""

from __future__ import annotations

import time

import numpy as np

from study import backend, methods, runtime
from study.harness.config import load_figure_config
from study.impostor.envmap import EnvMap
from study.impostor.sdf import SdfGrid, build_grid
from study.impostor.views import Captured, SdfSpec
from study.reference.embree import Tracer


def main() -> None:
    mi = runtime.mitsuba()
    B = backend.get("numpy")
    print("scene        res  build_s  field_p50_m  field_p99_m  trace_p50_m  trace_p99_m  trace>1mm  lookups")
    for cfg in ("configs/fig5.toml", "configs/fig_cornell.toml"):
        _, s, _ = load_figure_config(cfg)
        mesh, o = s.mesh(), np.asarray(s.reference.point, float)
        tracer = Tracer(mesh)
        lo_b, hi_b = (np.asarray(b, float) for b in s.bounds())
        rng = np.random.default_rng(5)
        w = lo_b + (hi_b - lo_b) * rng.uniform(0.1, 0.9, (3000, 3))
        d = rng.normal(size=w.shape)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        exact = tracer.intersect(w, d)["point"]
        for res in (32, 64, 128):
            spec = SdfSpec(res=res)
            t0 = time.perf_counter()
            grid, lo, h = build_grid(mesh.vertices, mesh.faces, s.bounds(), spec)
            build = time.perf_counter() - t0
            side = h * (res - 1)
            sc = mi.load_dict(
                {
                    "type": "scene",
                    "f": {
                        "type": "sdfgrid",
                        "grid": mi.TensorXf(np.ascontiguousarray(grid[..., None] / side)),
                        "to_world": mi.ScalarTransform4f().translate([float(c) for c in lo]).scale(side),
                    },
                }
            )
            ray = mi.Ray3f(
                mi.Point3f(*(w[:, i] for i in range(3))), mi.Vector3f(*(d[:, i] for i in range(3)))
            )
            t = np.asarray(sc.ray_intersect(ray).t, float)
            ref = w + d * t[:, None]
            env = Captured(
                impostor=EnvMap(np.ones((6, 8, 8, 4), np.float32), B),
                reference=tuple(o),
                sdfs={spec: SdfGrid(grid, lo, h, o, B)},
            )
            with np.errstate(all="ignore"):
                tr = methods.make("sdf", res=res).trace(B, env, B.vec(w - o), B.vec(d), check_origin=False)
            shown = B.to_numpy(tr.shown) + o
            free = env.sdfs[spec].distance(B.vec(w - o)) > 0  # origins in free space (not inside a solid)
            ok = np.isfinite(t) & B.numpy(tr.valid) & np.isfinite(exact).all(1) & free
            field = np.linalg.norm(ref[ok] - exact[ok], axis=1)
            trace = np.linalg.norm(shown[ok] - ref[ok], axis=1)
            print(
                f"{cfg.split('/')[-1][:-5]:12s} {res:4d} {build:8.2f} {np.median(field):12.2e} "
                f"{np.quantile(field, 0.99):12.2e} {np.median(trace):12.2e} {np.quantile(trace, 0.99):12.2e} "
                f"{np.mean(trace > 1e-3):10.4f} {np.mean(B.numpy(tr.lookups)):8.1f}"
            )


if __name__ == "__main__":
    main()
