"""Directory names that are not UTF-8 (a Linux file name is bytes): a scene in such a folder, an --out of such a
name and such a folder under reports/ work like any other (they once ended in "internal error", exit 4); the
names are shown with Python's surrogate escapes."""

import os
import subprocess
from pathlib import Path

import pytest

from tests.robustness.test_bad_inputs import DEFAULT, FIG

ROOT = Path(__file__).resolve().parents[2]
STUDY = os.fsencode(ROOT / ".venv" / "bin" / "study")


def run(*args: bytes):
    return subprocess.run([STUDY, *args], capture_output=True, timeout=600)


@pytest.mark.slow
def test_non_utf8_scene_folder_and_out(tmp_path):
    base = os.fsencode(tmp_path)
    folder = base + b"/sc\xff"
    os.makedirs(folder)
    with open(folder + b"/fig.toml", "w") as f:
        f.write(FIG.format(**DEFAULT))
    out = base + b"/out\xfe"
    p = run(b"figure", b"fig4", b"--config", folder + b"/fig.toml", b"--out", out)
    assert p.returncode == 0, p.stderr
    assert os.path.isfile(out + b"/metrics.csv") and os.path.isfile(out + b"/metadata.json")
    os.makedirs(base + b"/reports/fig\xfd")
    os.rename(out, base + b"/reports/fig4")
    p = run(b"report", b"--reports", base + b"/reports")
    assert p.returncode == 0, p.stderr
    assert "fig4" in (tmp_path / "reports" / "index.md").read_text()
