"""Compare the numbers of two report trees (e.g. before and after a refactoring), timing columns aside.

    python scripts/compare_reports.py OLD_REPORTS NEW_REPORTS [--rtol 1e-9]

Rows are matched by (case, method label); labels are made canonical through the method registry (a label written
before a method declared its knob, such as "layered", becomes today's "layered(linear_steps=30)"). For every
table both trees hold, prints the rows matched, rows only on one side, and per numeric column the largest
difference; exits 1 if any value differs by more than rtol (relative) or a row is missing.
"""

from __future__ import annotations

import ast
import math
import sys
from pathlib import Path

from study import methods
from study.tables import TIMING_COLUMNS, read_csv

TABLES = {
    "fig4/metrics.csv": "fig4/metrics.csv",
    "fig5/metrics.csv": "fig5/metrics.csv",
    "fig6/metrics.csv": "fig6/metrics.csv",
    "fig8/fig8.csv": "fig8/fig8.csv",
    "fig8/sweep.csv": "fig8/sweep/results.csv",
    "fig8/sweep/results.csv": "fig8/sweep/results.csv",
    "sweep-sweep/results.csv": "sweep-sweep/results.csv",
    "baseline/results.csv": "baseline/results.csv",
}
SKIP = set(TIMING_COLUMNS) | {"seconds_per_map", "iterations", "knob_value", "family", "knob", "label"}


def canonical(label: str) -> str:
    name, _, rest = label.partition("(")
    if name not in methods.REGISTRY:
        return label
    kw = {}
    if rest:
        for part in rest.rstrip(")").split(", "):
            k, _, v = part.partition("=")
            kw[k] = ast.literal_eval(v)
    return methods.make(name, **kw).label


def key(r: dict) -> tuple:
    if "caustic_res" in r:  # caustic tables: one row per resolution × method
        return (str(r["caustic_res"]), canonical(r["label"]))
    return (r.get("case", ""), canonical(r["label"]))


def compare(old: Path, new: Path, rtol: float) -> bool:
    ok = True
    for o_name, n_name in TABLES.items():
        po, pn = old / o_name, new / n_name
        if not po.is_file() or not pn.is_file() or (o_name != n_name and (old / n_name).is_file()):
            continue
        a = {key(r): r for r in read_csv(po)}
        b = {key(r): r for r in read_csv(pn)}
        common = a.keys() & b.keys()
        only_a, only_b = sorted(a.keys() - b.keys()), sorted(b.keys() - a.keys())
        worst: dict[str, tuple[float, tuple]] = {}
        for k in common:
            for col, x in a[k].items():
                y = b[k].get(col)
                if (
                    col in SKIP
                    or col.startswith("axis:")
                    or not isinstance(x, float)
                    or not isinstance(y, float)
                ):
                    continue
                if math.isnan(x) and math.isnan(y):
                    continue
                d = (
                    abs(x - y) / max(abs(x), 1e-12)
                    if not (math.isinf(x) or math.isinf(y))
                    else (0 if x == y else 1)
                )
                if d > worst.get(col, (-1,))[0]:
                    worst[col] = (d, k)
        bad = {c: v for c, v in worst.items() if v[0] > rtol}
        ok &= not bad and not only_a
        print(
            f"{o_name} → {n_name}: {len(common)} rows matched, {len(only_a)} only before, {len(only_b)} only now"
        )
        for k in only_a[:5]:
            print(f"   only before: {k}")
        for c, (d, k) in sorted(bad.items(), key=lambda kv: -kv[1][0])[:12]:
            print(f"   {c}: relative difference {d:.3g} at {k}: {a[k][c]!r} → {b[k][c]!r}")
        if not bad:
            print(f"   every numeric column equal within rtol {rtol:g}")
    return ok


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    rtol = float(sys.argv[sys.argv.index("--rtol") + 1]) if "--rtol" in sys.argv else 1e-9
    sys.exit(0 if compare(Path(args[0]), Path(args[1]), rtol) else 1)
