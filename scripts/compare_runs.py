"""Whether two runs of one command made the same numbers, and where they first part: their render caches entry by
entry (the same key in both: a stage whose inputs were equal), then their tables value by value.

    python scripts/compare_runs.py CACHE_A CACHE_B [TABLE_A TABLE_B]

Per cache kind (``<root>/<kind>/<key>.npy``, study.cache): how many entries both hold, how many differ and by how
much (the largest absolute difference, the share of differing elements); per table column (rows matched by
case, label and knob, ``study.tables.read_csv``): how many rows differ and the largest relative difference.
Written for the GPU runs of issue 52 (are two CUDA runs of fig4 the same, and which stage makes them differ?);
exit 0 either way.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np


def caches(a: Path, b: Path) -> list[str]:
    out = []
    for kind in sorted(p.name for p in a.iterdir() if p.is_dir() and (b / p.name).is_dir()):
        both = sorted(p.name for p in (a / kind).glob("*.npy") if (b / kind / p.name).exists())
        diff, largest, share = 0, 0.0, 0.0
        for name in both:
            x, y = np.load(a / kind / name), np.load(b / kind / name)
            if x.shape != y.shape:
                diff, largest, share = diff + 1, float("inf"), 1.0
                continue
            same = (x == y) | (np.isnan(x) & np.isnan(y))
            if not same.all():
                diff += 1
                d = np.abs(x.astype(float) - y.astype(float))[~same]
                largest = max(largest, float(np.nanmax(d)) if np.isfinite(d).any() else float("inf"))
                share = max(share, float((~same).mean()))
        only = len(list((a / kind).glob("*.npy"))) - len(both)
        out.append(
            f"cache {kind}: {len(both)} in both ({only} only in A), {diff} differ"
            + (f" (largest |Δ| {largest:.3g}, at most {share:.2%} of an entry's elements)" if diff else "")
        )
    return out


def tables(a: Path, b: Path) -> list[str]:
    from study.tables import read_csv

    ra, rb = read_csv(a), read_csv(b)
    keys = [k for k in ("case", "label", "knob", "knob_value") if ra and rb and k in ra[0] and k in rb[0]]
    ia, ib = ({tuple(str(r.get(k)) for k in keys): r for r in rows} for rows in (ra, rb))
    common = [k for k in ia if k in ib]
    out = [f"tables: {len(ra)} and {len(rb)} rows, {len(common)} matched by {', '.join(keys)}"]
    for col in [c for c in ra[0] if c in rb[0]] if common else []:
        differ, largest = [], 0.0
        for k in common:
            x, y = ia[k][col], ib[k][col]
            if isinstance(x, float) and isinstance(y, float):
                if x == y or (x != x and y != y):
                    continue
                differ.append(k)
                largest = max(largest, abs(x - y) / max(abs(x), abs(y)) if x == x and y == y else math.inf)
            elif x != y:
                differ, largest = [*differ, k], math.inf
        if differ:
            rows = "; ".join("/".join(k) for k in differ[:3]) + (" …" if len(differ) > 3 else "")
            out.append(f"  {col}: {len(differ)} rows differ, largest relative {largest:.3g} (e.g. {rows})")
    if len(out) == 1:
        out.append("  every value equal")
    return out


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 4):
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    lines = caches(Path(argv[0]), Path(argv[1]))
    if len(argv) == 4:
        lines += tables(Path(argv[2]), Path(argv[3]))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
