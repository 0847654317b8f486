"""The report's headline and per-table verdicts (study.report.summary) from the committed tables under
reports/, printed as Markdown; with ``--curves DIR`` also the wrong-fraction-versus-tolerance plot of every table
that has the fixed-tolerance columns (written by code after issue 24).

    PYTHONPATH=. .venv/bin/python scripts/headline.py [reports] [--curves DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from study.errors import StudyError
from study.outputs import plots
from study.report import summary
from study.report.report import results_table
from study.tables import markdown


def tables_of(reports: Path) -> dict[str, list[dict]]:
    figs = sorted(d for d in reports.glob("fig*") if (d / "metrics.csv").is_file())
    sweeps = sorted(d for d in reports.glob("sweep-*") if (d / "results.csv").is_file())
    out = {d.name: results_table(d / "metrics.csv") for d in figs}  # forged numbers: one line, exit 2
    out.update({d.name: results_table(d / "results.csv") for d in sweeps})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reports", nargs="?", default="reports")
    ap.add_argument("--curves", type=Path, help="write <table>-tolerance.png here")
    a = ap.parse_args()
    try:
        tables = tables_of(Path(a.reports))
    except StudyError as err:  # a malformed or impossible table: one line, exit 2
        print(f"error: {err}", file=sys.stderr)
        raise SystemExit(err.code) from None
    for b in summary.headline_blocks(tables):
        if b[0] == "h":
            print("#" * b[1], b[2], "\n")
        elif b[0] == "p":
            print(b[1], "\n")
        elif b[0] == "list":
            print("\n".join(f"- {t}" for t in b[1]), "\n")
        elif b[0] == "table":
            print(markdown(b[1], b[2]), "\n")
    if a.curves:
        a.curves.mkdir(parents=True, exist_ok=True)
        for name, tab in tables.items():
            rows = summary.tolerance_curve_rows(tab)
            if rows:
                plots.plot_tolerance_curve(rows, a.curves / f"{name}-tolerance.png", title=name)
                print(f"wrote {a.curves / f'{name}-tolerance.png'}")


if __name__ == "__main__":
    main()
