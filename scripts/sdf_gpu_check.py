"""sdf on the GPU (Dr.Jit CUDA, the field a hardware-filtered ``Texture3f``) against numpy on the same grid and rays:
fig5's room at 64³ and 128³, 3000 rays (tests/methods/test_methods_sdf.py's set). CUDA's texture units interpolate with
fixed-point weights (1/256 steps), so hits may move by a fraction of a millimetre; the script prints the fractions
of rays whose shown points agree within 1 mm and 1 cm, the lookups, and the traced rays per second of a frozen,
replayed call. Run on a GPU machine: ``.venv/bin/python scripts/sdf_gpu_check.py``."""

from __future__ import annotations

import time

import numpy as np

from study import backend, methods
from study.harness.config import load_figure_config
from study.impostor.envmap import EnvMap
from study.impostor.sdf import SdfGrid, build_grid
from study.impostor.views import Captured, SdfSpec
from study.reference.embree import Tracer


def main() -> None:
    _, s, _ = load_figure_config("configs/fig5.toml")
    mesh, o = s.mesh(), np.asarray(s.reference.point, float)
    imp = np.ones((6, 16, 16, 4), np.float32) * 3.0
    rng = np.random.default_rng(5)
    n = 3000
    x = np.r_[
        rng.uniform(-0.3, 0.3, (n // 2, 3)) + np.array([-0.9, 2.1, -0.9]),
        rng.uniform([-0.3, 0.3, -0.3], [1.7, 2.7, 1.7], (n - n // 2, 3)),
    ]
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    exact = Tracer(mesh).intersect(x, d)["point"]
    for res in (64, 128):
        spec = SdfSpec(res=res)
        grid, lo, h = build_grid(mesh.vertices, mesh.faces, s.bounds(), spec)
        out = {}
        for name in ("numpy", "cuda"):
            B = backend.get(name)
            env = Captured(
                impostor=EnvMap(imp, B), reference=tuple(o), sdfs={spec: SdfGrid(grid, lo, h, o, B)}
            )
            with np.errstate(all="ignore"):
                tr = methods.make("sdf", res=res).trace(B, env, B.vec(x - o), B.vec(d))
            out[name] = (B.to_numpy(tr.shown) + o, B.numpy(tr.valid), B.numpy(tr.lookups))
        (s0, v0, l0), (s1, v1, l1) = out["numpy"], out["cuda"]
        both = v0 & v1
        gap = np.linalg.norm(s0[both] - s1[both], axis=1)
        err = np.linalg.norm(s1[both] - exact[both], axis=1)
        print(
            f"{res}³: valid equal {np.mean(v0 == v1):.4f}; cuda vs numpy within 1 mm {np.mean(gap < 1e-3):.4f}, "
            f"1 cm {np.mean(gap < 1e-2):.4f}; cuda vs Embree within one voxel {np.mean(err < h):.4f}; "
            f"lookups numpy {l0.mean():.2f} cuda {l1.mean():.2f}"
        )
        B = backend.get("cuda")
        env = Captured(impostor=EnvMap(imp, B), reference=tuple(o), sdfs={spec: SdfGrid(grid, lo, h, o, B)})
        big = 1 << 20
        xb = np.tile(x, (big // n + 1, 1))[:big] - o
        db = np.tile(d, (big // n + 1, 1))[:big]
        X, R = B.vec(xb), B.vec(db)
        m = methods.make("sdf", res=res)
        for _ in range(2):
            t0 = time.perf_counter()
            tr = m.trace(B, env, X, R)
            B.eval(tr.shown.x, tr.shown.y, tr.shown.z, tr.valid)
            B.sync()
            dt = time.perf_counter() - t0
        print(f"{res}³: {big / dt / 1e6:.1f} M rays/s (unfrozen, second call, {big} rays)")


if __name__ == "__main__":
    main()
