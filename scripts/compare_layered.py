"""Figure 5 check: p95 angular error of ``layered`` against ``localized`` on scenes/columns.toml.

Runs the real pipeline (study.evaluate.case.run_case: Mitsuba impostor radiance, Embree distances and exact hits, the
layered impostor of study.impostor.layers) and prints one row per method. Goal (issue 4): layered's p95 below half of
localized's, both at 10 iterations.

    python scripts/compare_layered.py [--scene scenes/columns.toml] [--backend numpy] [--cache .cache] [--layers 3]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))     # this checkout's study, not an installed one

from study import methods
from study.cache import Cache
from study.evaluate.case import run_case
from study.scene import load_scene


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="scenes/columns.toml")
    ap.add_argument("--backend", default="numpy")
    ap.add_argument("--cache", default=".cache")
    ap.add_argument("--layers", type=int, default=3)
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="scene overrides, e.g. render.cube_res=128 (values parsed as Python literals)")
    a = ap.parse_args()
    scene = load_scene(a.scene)
    if a.set:
        import ast
        scene = scene.with_updates({k: ast.literal_eval(v) for k, v in (s.split("=", 1) for s in a.set)})
    ms = [methods.make("localized", iterations=10), methods.make("layered", iterations=10, layers=a.layers),
          methods.make("linear_secant"), methods.make("proxy_box"), methods.make("proxy_sphere")]
    out = run_case(scene, ms, backend=a.backend, cache=Cache(a.cache), keep_images=False)
    print(f"scene {a.scene}, backend {a.backend}, rays {out.rows[0]['rays']}, "
          f"occluded fraction {out.rows[0]['occluded_fraction']:.3f}")
    print(f"{'method':40s} {'median°':>9s} {'p95°':>9s} {'max°':>8s} {'valid':>6s} {'lookups':>7s}")
    for r in out.rows:
        print(f"{r['label']:40s} {r['angle_median_deg']:9.3g} {r['angle_p95_deg']:9.3g} {r['angle_max_deg']:8.2f} "
              f"{r['valid_fraction']:6.3f} {r['lookups_per_ray']:7d}")
    p95 = {r["method"]: r["angle_p95_deg"] for r in out.rows}
    ratio = p95["layered"] / p95["localized"]
    print(f"p95 layered / localized = {p95['layered']:.3g} / {p95['localized']:.3g} = {ratio:.3g} "
          f"({'below' if ratio < 0.5 else 'NOT below'} one half)")
    return 0 if ratio < 0.5 else 1


if __name__ == "__main__":
    raise SystemExit(main())
