"""Print the error split (study.measure.split) of a few shipped cases at a chosen size: per method, every term with
its 95 % pixel-bootstrap interval, in MSE (linear radiance²), and whether the parts add up to the total; then the
paper's claims judged on these cases.

Run: ``python scripts/split_table.py [--small] [--cache DIR]`` (``--small``: camera 64², cube 64², 16 spp, the
size the tests use; without it the configs' own sizes). Deterministic for the configs' seeds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from study import methods as registry
from study.cache import Cache
from study.harness.config import load_figure_config
from study.measure.case import run_case
from study.measure.split import TERMS
from study.report.claims import judge_claims

SMALL = {
    "camera.width": 64,
    "camera.height": 64,
    "render.cube_res": 64,
    "render.cube_spp": 16,
    "render.spp": 16,
}
METHODS = ("classical", "localized", "proxy_box", "layered")


def cases(small: bool):
    """(name, scene): fig4's farthest position, fig5's first, the Cornell box's mirror sphere, the attic."""
    import tomllib

    for cfg_path, pick in (
        ("configs/fig4.toml", -1),
        ("configs/fig5.toml", 0),
        ("configs/fig_cornell.toml", 0),
    ):
        cfg, scene, _ = load_figure_config(cfg_path)
        raw = tomllib.loads(open(cfg_path).read())
        upd = {}
        if "positions" in raw:
            upd["object.center"] = raw["positions"][pick]
        if "cases" in raw:
            upd.update({k: v for k, v in raw["cases"][pick].items() if k != "name"})
        if small:
            upd.update(SMALL)
        yield f"{cfg_path.split('/')[-1][:-5]}[{pick}]", scene.with_updates(upd)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--small", action="store_true")
    ap.add_argument("--cache", default=None)
    a = ap.parse_args()
    ms = [registry.make(n) for n in METHODS]
    every = []
    for name, scene in cases(a.small):
        t0 = time.perf_counter()
        rows = run_case(
            scene, ms, cache=Cache(a.cache), case_id=name, keep_images=True
        ).rows  # with intervals
        every += rows
        print(f"\n## {name}  ({time.perf_counter() - t0:.0f} s)")
        cols = ["total", *TERMS, "residual"]
        print("| method | pixels (held) | " + " | ".join(cols) + " | sums |")
        print("|---" * (len(cols) + 3) + "|")
        for r in rows:
            if r["label"] == "truth_at_hit":
                continue
            cells = [
                f"{r[f'dec_{k}']:.2e} [{r[f'dec_{k}_lo']:.1e}, {r[f'dec_{k}_hi']:.1e}]"
                if np.isfinite(r[f"dec_{k}"])
                else "–"
                for k in cols
            ]
            print(
                f"| {r['label']} | {r['held_pixels'] + r['unheld_pixels']} ({r['held_pixels']}) | "
                + " | ".join(cells)
                + f" | {'yes' if r['dec_sums'] == 1 else 'no'} |"
            )
    print("\n## The claims on these cases (study/report/claims.py)")
    for cl, v in judge_claims(every):
        print(f"- {cl.id}: {'holds' if v.ok else 'FAILS'} — {v.subset}; {v.n}; {v.number}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
