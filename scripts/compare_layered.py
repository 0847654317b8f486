"""Figure 5 check: how often ``layered``, ``localized`` and ``linear_secant`` show a wrong point.

Runs the real pipeline's pieces (study.measure.case: the cached impostor and layered impostor, the object's
secondary rays, Embree exact hits, ``method.trace``) on the cases of a figure config (default configs/fig5.toml)
and prints, per case and method:

- wrong_hidden: share of the rays whose exact hit is hidden from the reference point o (``occluded`` as in
  study.measure.case) whose shown point is not *correct*, |shown − exact| > eps with
  eps = max(0.01 m, |exact − o| · 2 / cube_res); an invalid ray (NaN) counts as wrong;
- wrong_visible: the same share over the rays whose exact hit o sees;
- lookups per ray (the mean of what the rays spent, ``Trace.lookups``) and seconds of ``method.trace`` (backend
  included, no capture);
- per case, ``no layer``: the share of hidden-hit rays for which no layer of the layered impostor holds the exact
  hit (|layer_k distance towards the hit − |exact − o|| > eps for every k, bilinear lookup as the search sees it).

    python scripts/compare_layered.py [--config configs/fig5.toml] [--cases p0 p1 p2] [--backend numpy]
        [--layered KEY=VALUE ...] [--linear KEY=VALUE ...] [--cache .cache]

Goal: layered's wrong_hidden ≤ 5 % on fig5 p0 (exit status 1 otherwise).
"""

from __future__ import annotations

import argparse
import ast
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's study, not an installed one

from study import backend as backends
from study import methods
from study.cache import Cache
from study.harness.config import load_figure_config
from study.impostor.envmap import EnvMap
from study.impostor.layers import layered_impostor
from study.measure.case import capture_views, impostor
from study.optics import shading
from study.reference.embree import Tracer


def kv(items):
    return {k: ast.literal_eval(v) for k, v in (s.split("=", 1) for s in items)}


def measure(scene, ms, *, backend, cache):
    """Rows (dict per method) and the share of hidden hits no layer holds, for one scene."""
    B, nb = backends.get(backend), backends.get("numpy")
    tracer = Tracer(scene.mesh())
    o = np.asarray(scene.reference.point, float)
    imp = impostor(scene, cache, tracer)
    rays = shading.object_rays(scene)
    exact = tracer.intersect(*rays.exact_rays())["point"]
    to_hit = exact - o
    hit_dist = np.linalg.norm(to_hit, axis=-1)
    seen = tracer.distance(np.broadcast_to(o, to_hit.shape), to_hit / hit_dist[:, None])
    hidden = seen < hit_dist * (1 - 1e-4) - 1e-5
    eps = np.maximum(0.01, hit_dist * 2 / scene.render.cube_res)
    n_layers = max(m.layers_needed() for m in ms)
    tex = layered_impostor(scene, cache, n_layers, imp.radiance, tracer) if n_layers > 1 else None
    env = capture_views(scene, ms, imp, B, cache=cache, tracer=tracer)
    held = np.zeros(len(exact), bool)  # some layer holds the exact hit (within eps)
    for t in tex if tex is not None else [imp.texels()]:
        d = np.asarray(EnvMap(t, nb).distance(nb.vec(to_hit)), float)
        held |= np.abs(d - hit_dist) <= eps
    x, R = B.vec(rays.x - o), B.vec(rays.R)
    rows = []
    for m in ms:
        t0 = time.perf_counter()
        with np.errstate(divide="ignore", invalid="ignore"):
            tr = m.trace(B, env, x, R)
        B.eval(
            tr.shown.x,
            tr.shown.y,
            tr.shown.z,
            tr.radiance.x,
            tr.radiance.y,
            tr.radiance.z,
            tr.ratio,
            tr.valid,
        )
        shown = B.to_numpy(tr.shown).astype(np.float64) + o
        sec = time.perf_counter() - t0
        err = np.linalg.norm(shown - exact, axis=1)
        wrong = ~(err <= eps)  # NaN (invalid) is wrong
        rows.append(
            {
                "label": m.label,
                "wrong_hidden": wrong[hidden].mean() if hidden.any() else np.nan,
                "wrong_visible": wrong[~hidden].mean(),
                "lookups": float(np.mean(B.numpy(tr.lookups))),
                "seconds": sec,
                "wrong_hidden_held": wrong[hidden & held].mean() if (hidden & held).any() else np.nan,
            }
        )
    info = {
        "rays": len(exact),
        "hidden": int(hidden.sum()),
        "no_layer": float((~held[hidden]).mean()) if hidden.any() else np.nan,
        "layers": n_layers,
    }
    return rows, info


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="configs/fig5.toml")
    ap.add_argument("--cases", nargs="*", default=["p0", "p1", "p2"])
    ap.add_argument("--backend", default="numpy")
    ap.add_argument("--cache", default=".cache")
    ap.add_argument("--layered", nargs="*", default=[], metavar="KEY=VALUE", help="layered's parameters")
    ap.add_argument("--linear", nargs="*", default=[], metavar="KEY=VALUE", help="linear_secant's parameters")
    ap.add_argument("--only", nargs="*", default=None, help="method names to run (default: all three)")
    a = ap.parse_args()
    cfg, scene, _ = load_figure_config(a.config)
    ms = [
        methods.make("localized", iterations=10),
        methods.make("linear_secant", **kv(a.linear)),
        methods.make("layered", **kv(a.layered)),
    ]
    if a.only:
        ms = [m for m in ms if m.name in a.only]
    cache = Cache(a.cache)
    status = 0
    for cid, label, over in cfg.case_list():
        if cid not in a.cases:
            continue
        rows, info = measure(scene.with_updates(over), ms, backend=a.backend, cache=cache)
        print(
            f"\n{a.config} {cid} {label}: {info['rays']} rays, {info['hidden']} with a hidden hit; "
            f"no layer of {info['layers']} holds {100 * info['no_layer']:.1f} % of them"
        )
        print(
            f"{'method':58s} {'wrong_hidden':>12s} {'(held)':>7s} {'wrong_visible':>13s} {'lookups':>7s} "
            f"{'seconds':>8s}"
        )
        for r in rows:
            print(
                f"{r['label']:58s} {100 * r['wrong_hidden']:11.1f}% {100 * r['wrong_hidden_held']:6.1f}% "
                f"{100 * r['wrong_visible']:12.2f}% {r['lookups']:7d} {r['seconds']:8.2f}"
            )
            if cid == "p0" and r["label"].startswith("layered") and not r["wrong_hidden"] <= 0.05:
                status = 1
    return status


if __name__ == "__main__":
    raise SystemExit(main())
