"""The tidy results table: one row per case × method, written as CSV atomically (temp file + rename)."""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path

from study.capture import _atomic_write

#: Column order of every results table; extra keys follow in the order first seen.
COLUMNS = ["case", "method", "label", "iterations", "cube_res", "object_x", "object_y", "object_z", "displacement",
           "angle_median_deg", "angle_p95_deg", "angle_max_deg", "dist_median",
           "rmse_oracle", "psnr_oracle", "ssim_oracle", "flip_oracle",
           "rmse_mitsuba", "psnr_mitsuba", "ssim_mitsuba", "flip_mitsuba",
           "occluded_fraction", "valid_fraction", "ratio_residual_median", "lookups_per_ray", "rays",
           "backend", "seconds"]


def _fmt(v):
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return repr(v) if math.isfinite(v) else ("inf" if v > 0 else "-inf")
    return v


def columns_of(rows: list[dict]) -> list[str]:
    extra = [k for r in rows for k in r if k not in COLUMNS]
    return [c for c in COLUMNS if any(c in r for r in rows)] + list(dict.fromkeys(extra))


def to_csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns_of(rows), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _fmt(v) for k, v in r.items()})
    return buf.getvalue()


def write_csv(rows: list[dict], path: str | Path) -> None:
    _atomic_write(Path(path), to_csv(rows).encode())


def read_csv(path: str | Path) -> list[dict]:
    """Rows with numbers parsed back to float (empty → NaN)."""
    out = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row = {}
            for k, v in r.items():
                try:
                    row[k] = float(v) if v != "" else math.nan
                except ValueError:
                    row[k] = v
            out.append(row)
    return out
