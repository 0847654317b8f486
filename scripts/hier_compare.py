"""The hierarchical search against the texel march on the study's own cases: same wrong fraction?

    PYTHONPATH=. python scripts/hier_compare.py [fig4] [fig5] [sweep] [--backend llvm] [--out DIR] [--reduced]

Runs fig4, fig5 (``study figure``) and the main sweep (``study sweep``; with ``--reduced`` its axes cut to
cube_res 128: 12 of 48 cases) with the methods linear_secant and
layered, each with ``hierarchical`` True and False, and prints per table the wrong fraction of each pair, case by
case, and the largest difference. The target: within 0.1 percentage point. Configs are written beside the
outputs (``--out``, default /tmp/hier-compare); the cache is ``--out``/cache.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tomllib
from pathlib import Path

from study.tables import read_csv

ROOT = Path(__file__).resolve().parent.parent
METHODS = [
    {"name": "linear_secant", "hierarchical": True},
    {"name": "linear_secant", "hierarchical": False},
    {"name": "layered", "hierarchical": True},
    {"name": "layered", "hierarchical": False},
]


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f'"{k}" = {toml_value(x)}' for k, x in v.items()) + " }"
    return repr(v)


def write_toml(d: dict, path: Path) -> None:
    lines, tables = [], []
    for k, v in d.items():
        (tables if isinstance(v, dict) and k in ("overrides", "axes") else lines).append((k, v))
    out = [f'"{k}" = {toml_value(v)}' for k, v in lines]

    def table(name, t):
        sub = {k: v for k, v in t.items() if isinstance(v, dict) and name == "axes" and k == "columns"}
        out.append(f"\n[{name}]")
        out.extend(f'"{k}" = {toml_value(v)}' for k, v in t.items() if k not in sub)
        for k, v in sub.items():
            for kk, vv in v.items():
                out.append(f"\n[{name}.{k}.{kk}]")
                out.extend(f'"{a}" = {toml_value(b)}' for a, b in vv.items())

    for k, v in tables:
        table(k, v)
    path.write_text("\n".join(out) + "\n")


def config(name: str, out: Path, reduced: bool) -> Path:
    d = tomllib.loads((ROOT / "configs" / f"{name}.toml").read_text())
    d["scene"] = str((ROOT / "configs" / d["scene"]).resolve())
    d["methods"] = METHODS
    if "grid" in d:
        d["grid"] = ["linear_secant", "layered"]
    if reduced and name == "sweep":
        d["axes"]["render.cube_res"] = [128]
    path = out / f"{name}.toml"
    write_toml(d, path)
    return path


def compare(table: Path) -> float:
    rows = read_csv(table)
    pairs: dict = {}
    for r in rows:
        if r["method"] not in ("linear_secant", "layered"):
            continue
        hier = "hierarchical=False" not in r["label"]
        pairs.setdefault((r["case"], r["method"]), {})[hier] = float(r["wrong_fraction"])
    worst = 0.0
    for (case, m), p in sorted(pairs.items()):
        if len(p) == 2:
            diff = 100 * (p[True] - p[False])
            worst = max(worst, abs(diff))
            print(
                f"  {case:40s} {m:14s} texel {100 * p[False]:7.3f} %  hier {100 * p[True]:7.3f} %  Δ {diff:+.3f} pp"
            )
    print(f"  largest |Δ| {worst:.3f} pp over {len(pairs)} (case, method) pairs")
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tables", nargs="*", default=["fig4", "fig5", "sweep"])
    ap.add_argument("--backend", default="llvm")
    ap.add_argument("--out", type=Path, default=Path("/tmp/hier-compare"))
    ap.add_argument("--reduced", action="store_true")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    for name in a.tables:
        cfg = config(name, a.out, a.reduced)
        cmd = "sweep" if name == "sweep" else "figure"
        where = [str(cfg)] if cmd == "sweep" else ["--config", str(cfg)]
        args = [sys.executable, "-m", "study.cli", cmd, *where, "--out", str(a.out / name)]
        args += ["--backend", a.backend, "--cache", str(a.out / "cache")]
        if cmd == "sweep":
            args += ["--no-plots", "--jobs", "2"]
        subprocess.run(args, check=True)
        table = a.out / name / ("results.csv" if cmd == "sweep" else "metrics.csv")
        print(f"{name}:")
        compare(table)


if __name__ == "__main__":
    main()
