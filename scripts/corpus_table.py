"""The corpus table of issue 54: every entry file of the public corpus (tests/assets/corpus/manifest.json) run as
``study run FILE`` would run it — its placement automatic, its picture checked (:mod:`study.measure.worth`) — at a
small size, one markdown row per file: the object's share of the frame, the black and clipped shares of Mitsuba's
picture, the share of the object's rays that mirror the void, and the one line the run prints about its picture
("ok" where it prints none), or the one line a refused file gets.

    PYTHONPATH=$PWD .venv/bin/python scripts/corpus_table.py > reports/corpus.md

Small: 48² pixels, 32² cube faces, 4 samples per pixel and per texel, one ray per pixel, the methods classical and
localized (the worth columns depend on the scene, its placement and Mitsuba's picture, not on the methods).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CORPUS = ROOT / "tests" / "assets" / "corpus"
SMALL = {
    "camera.width": 48,
    "camera.height": 48,
    "render.cube_res": 32,
    "render.spp": 4,
    "render.cube_spp": 4,
    "render.supersample": 1,
}
METHODS = ["classical", "localized"]


def row(entry: dict) -> list[str]:
    """One markdown row for the corpus entry ``entry`` (its manifest record)."""
    import study
    from study.errors import StudyError
    from study.measure import worth

    path = CORPUS / entry["path"]
    t0 = time.perf_counter()
    try:
        res = study.evaluate(str(path), METHODS, cache=None, overrides=SMALL)
    except StudyError as err:
        line = str(err).strip().splitlines()[-1].replace(f"{ROOT}/", "")  # the table names repository paths
        return [entry["path"], "–", "–", "–", "–", f"refused: {line}", f"{time.perf_counter() - t0:.0f}"]
    values = res.table.iloc[0].to_dict()
    fmt = lambda k: "–" if not math.isfinite(float(values.get(k, math.nan))) else f"{float(values[k]):.3f}"  # noqa: E731
    line = worth.verdict(values) or "ok"
    cells = [fmt(k) for k in ("object_share", "black_share", "clipped_share", "mirrored_void")]
    return [entry["path"], *cells, line.replace("|", "/"), f"{time.perf_counter() - t0:.0f}"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", action="append", default=[], help="run only entries whose path contains this")
    a = ap.parse_args(argv)
    manifest = json.loads((CORPUS / "manifest.json").read_text())
    entries = [e for e in manifest if not a.only or any(s in e["path"] for s in a.only)]
    head = ["file", "object share", "black share", "clipped share", "mirrored void", "the line printed", "s"]
    print("# The corpus, run as `study run FILE` at a small size\n")
    print(
        "Written by `scripts/corpus_table.py` (48², 32² cube faces, 4 spp; see its docstring). One row per entry"
    )
    print('file of tests/assets/corpus/manifest.json; "s": seconds on the machine that wrote it.\n')
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for e in entries:
        print("| " + " | ".join(row(e)) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
