"""Write study/stats/data/study_fields.npz: the calibration's error templates taken from study's own output
(study.stats.calibration's rows on study's own error maps). One small case of scenes/room.toml (96 × 96 px,
fov 40°, cube_res 64, 16 spp, numpy backend): classical's per-pixel RMS error against truth_at_hit (a reflected
edge: the error sits in a thin streak where a bright edge of the room is reflected at the wrong place) and the
wrong-hit mask of localized(iterations=0) (its majority outcome is not the exact hit: a large connected region),
both cropped to the object's bounding box and zero-padded to a square (0 off the object), float32 / uint8.

    PYTHONPATH=. .venv/bin/python scripts/make_study_fields.py [--out PATH]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import study

OUT = Path(__file__).resolve().parents[1] / "study" / "stats" / "data" / "study_fields.npz"
SETTINGS = {
    "render.cube_res": 64,
    "render.spp": 16,
    "render.cube_spp": 16,
    "camera.width": 96,
    "camera.height": 96,
    "camera.fov": 40.0,
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args()
    scene = study.load_scene("scenes/room.toml", **SETTINGS)
    res = study.evaluate(scene, methods=["classical", "localized(iterations=0)"], backend="numpy")
    err = np.asarray(res.error_maps["classical"], float)
    outcome = np.asarray(res.outcome_maps["localized(iterations=0)"], float)
    ys, xs = np.nonzero(np.isfinite(err))
    crop = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
    side = max(ys.max() - ys.min(), xs.max() - xs.min()) + 1
    edge, wrong = np.zeros((side, side), np.float32), np.zeros((side, side), np.uint8)
    e, o = err[crop], outcome[crop]
    edge[: e.shape[0], : e.shape[1]] = np.nan_to_num(e)
    wrong[: o.shape[0], : o.shape[1]] = np.nan_to_num(o) > 0
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(a.out, edge=edge, wrong=wrong)
    print(
        f"{a.out}: {side} × {side} px, object {int(np.isfinite(e).sum())} px, wrong-hit share {wrong.mean():.3f}"
    )


if __name__ == "__main__":
    main()
