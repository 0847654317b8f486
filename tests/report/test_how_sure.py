"""The README's "How sure" paragraph is written by code from the committed tables (issue 53 item 5): significance
counted over distinct geometries (scripts/headline.py --readme → study.report.summary.readme_how_sure)."""

import subprocess
import sys
from pathlib import Path

from conftest import load_script

from study.report import summary

ROOT = Path(__file__).resolve().parents[2]


def _headline():
    return load_script("headline")


def test_the_readmes_how_sure_is_the_generated_one():
    """Regenerate with `PYTHONPATH=. .venv/bin/python scripts/headline.py --readme README.md` after the tables."""
    head = _headline()
    want = summary.readme_how_sure(head.tables_of(ROOT / "reports"))
    got = head.HOW_SURE.search((ROOT / "README.md").read_text())
    assert got and " ".join(got.group(0).split()) == " ".join(want.split()), (got and got.group(0), want)
    assert "distinct geometries" in want


def test_readme_rewrite_keeps_the_rest_and_refuses_a_readme_without_the_paragraph(tmp_path):
    head = _headline()
    readme = tmp_path / "README.md"
    readme.write_text("# t\n\n- **How sure:** by hand,\n  9 of 12.\n\nAfter.\n")
    head.write_how_sure(readme, "- **How sure:** generated.")
    assert readme.read_text() == "# t\n\n- **How sure:** generated.\n\nAfter.\n"
    readme.write_text("# t\n\nnothing\n")
    res = subprocess.run(
        [
            sys.executable,
            str(ROOT / "scripts" / "headline.py"),
            str(tmp_path / "none"),
            "--readme",
            str(readme),
        ],
        capture_output=True,
        text=True,
        env={"PYTHONPATH": str(ROOT)},
    )
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert "How sure" in res.stderr and readme.read_text() == "# t\n\nnothing\n"
