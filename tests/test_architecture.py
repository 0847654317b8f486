"""The house rules of study, checked: the layer contracts in pyproject.toml (import-linter), no import cycle, no
module over 460 lines (ruff-formatted), the map of the house in docs/architecture.md up to date, and a README short
enough to read."""

import textwrap
from pathlib import Path

from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parents[1]
MAX_LINES = 460


def test_layer_contracts_hold():
    """import-linter's contracts of pyproject.toml: lower layers never import upper ones, no cycles."""
    assert lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True) == 0


def test_layer_contract_catches_an_upward_import(tmp_path, monkeypatch):
    """The same kind of contract on a two-layer toy package, with the lower layer importing the upper: broken."""
    pkg = tmp_path / "toy"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "high.py").write_text("X = 1\n")
    (pkg / "low.py").write_text("from toy.high import X\n")
    (tmp_path / "toy.toml").write_text(
        textwrap.dedent("""
        [tool.importlinter]
        root_package = "toy"
        [[tool.importlinter.contracts]]
        name = "layers"
        type = "layers"
        layers = ["toy.high", "toy.low"]
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert lint_imports(config_filename=str(tmp_path / "toy.toml"), no_cache=True) == 1


def test_no_module_is_over_460_lines():
    long = {
        str(p.relative_to(ROOT)): n
        for p in (ROOT / "study").rglob("*.py")
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    }
    assert not long, f"split these modules: {long}"


def test_ruff_lint_and_format_pass():
    """House style by a tool: `ruff check` and `ruff format --check` (settings in pyproject.toml) on the repository."""
    import subprocess
    import sys

    for args in (["check", "."], ["format", "--check", "."]):
        proc = subprocess.run([sys.executable, "-m", "ruff", *args], cwd=ROOT, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]


def test_ruff_catches_a_long_line(tmp_path):
    """The same settings flag a 130-character line (the check above can fail)."""
    import subprocess
    import sys

    bad = tmp_path / "bad.py"
    bad.write_text("x = " + repr("a" * 124) + "\n")
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--config", str(ROOT / "pyproject.toml"), str(bad)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1 and "E501" in proc.stdout


def test_every_package_says_what_it_owns():
    for init in (ROOT / "study").rglob("__init__.py"):
        doc = init.read_text().lstrip()
        assert doc.startswith('"""') and len(doc.split('"""')[1].split()) >= 8, f"{init}: no docstring"


def test_map_of_the_house_is_current():
    """docs/architecture.md's 'Where things are' is what scripts/house.py makes from the docstrings today."""
    import runpy

    house = runpy.run_path(str(ROOT / "scripts" / "house.py"))
    text = (ROOT / "docs" / "architecture.md").read_text()
    assert house["render"](text) == text, (
        "run `python scripts/house.py` to regenerate docs/architecture.md's map"
    )


def test_readme_is_at_most_8_kb():
    """The README leads with the finding and links to docs/ for the rest; it stays short."""
    size = len((ROOT / "README.md").read_bytes())
    assert size <= 8 * 1024, f"README.md is {size} bytes; move detail into docs/"


def test_readme_commands_and_links_hold():
    """The README's two commands are there as written, and every file it links to or shows exists."""
    import re

    readme = (ROOT / "README.md").read_text()
    for cmd in (
        "bash scripts/reproduce.sh",
        "bash scripts/test.sh",
        "PYTHONPATH=. .venv/bin/python scripts/headline.py",
    ):
        assert f"\n    {cmd}\n" in readme, f"README.md: `{cmd}` is not a command block of its own"
    targets = re.findall(r"\]\(([^)#]+)\)", readme)  # Markdown links and images
    assert "docs/images/fig5-case.png" in targets
    missing = [t for t in targets if "://" not in t and not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"
