"""The report's headline and per-table verdicts (study.report.summary) from the committed tables under
reports/, printed as Markdown; with ``--curves DIR`` also the wrong-fraction-versus-tolerance plot of every table
that has the fixed-tolerance columns (written by code after issue 24).

    PYTHONPATH=. .venv/bin/python scripts/headline.py [reports] [--curves DIR] [--readme README.md]

``--readme`` rewrites the README's "How sure" bullet (the paragraph that starts ``- **How sure:**``) from the same
tables (:func:`study.report.summary.readme_how_sure`: significance counted over distinct geometries), so that
paragraph is never typed by hand; run it after the tables are regenerated.
"""

from __future__ import annotations

import argparse
import re
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


#: the README's "How sure" bullet: from its first line to the blank line after it
HOW_SURE = re.compile(r"^- \*\*How sure:\*\*.*?(?=\n\s*\n)", re.S | re.M)


def write_how_sure(readme: Path, bullet: str) -> None:
    """Replace the README's "How sure" bullet with ``bullet`` (atomically); one line and exit 2 if it has none."""
    from study.io import atomic_write

    text = readme.read_text()
    if not HOW_SURE.search(text):
        print(f"{readme}: no paragraph starting '- **How sure:**' to rewrite", file=sys.stderr)
        sys.exit(2)
    atomic_write(readme, HOW_SURE.sub(lambda _: bullet, text, count=1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reports", nargs="?", default="reports")
    ap.add_argument("--curves", type=Path, help="write <table>-tolerance.png here")
    ap.add_argument("--readme", type=Path, help="rewrite this README's 'How sure' bullet from the tables")
    a = ap.parse_args()
    try:
        tables = tables_of(Path(a.reports))
    except StudyError as err:  # a malformed or impossible table: one line, exit 2
        print(f"error: {err}", file=sys.stderr)
        raise SystemExit(err.code) from None
    if a.readme:
        write_how_sure(a.readme, summary.readme_how_sure(tables))
        print(f"wrote the 'How sure' bullet of {a.readme}")
        return
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
