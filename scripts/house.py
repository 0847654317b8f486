"""Regenerate the map of the house ("Where things are" in docs/architecture.md) from the package and module
docstrings.

python scripts/house.py           # rewrite the table between the markers in docs/architecture.md
python scripts/house.py --check   # exit 1 if docs/architecture.md is not up to date (tests/test_architecture.py)
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAP = ROOT / "docs" / "architecture.md"  # the file that holds the map, between the markers
BEGIN, END = "<!-- house:begin (scripts/house.py) -->", "<!-- house:end -->"
#: top to bottom, as the layers of pyproject.toml
ORDER = [
    "cli",
    "api.py",
    "outputs",
    "bench",
    "caustics",
    "harness",
    "measure",
    "optics",
    "methods",
    "impostor",
    "reference",
    "scene",
    "cache.py",
    "validation.py",
    "tables.py",
    "backend.py",
    "vec.py",
    "io.py",
    "owned.py",
    "runtime.py",
    "stats",
    "codehash.py",
    "errors.py",
    "progress.py",
]


def _first_sentence(path: Path) -> str:
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    text = " ".join(doc.split("\n\n")[0].split())  # the first paragraph
    for m in re.finditer(r"\.(?=\s|$)", text):  # its first sentence (not "ch. 17", "et al.")
        if not re.search(r"(\bch|\bal|e\.g|i\.e|\bvs|\d)$", text[: m.start()]):
            text = text[: m.end()]
            break
    return text.replace("|", "\\|")


def table() -> str:
    rows = ["| where | what |", "|---|---|"]
    for name in ORDER:
        p = ROOT / "study" / name
        if p.is_dir():
            rows.append(f"| `study/{name}/` | {_first_sentence(p / '__init__.py')} |")
            for mod in sorted([*p.glob("*.py"), *(d for d in p.iterdir() if (d / "__init__.py").is_file())]):
                if mod.is_dir():  # a package inside the package (scene/sources/): its modules under it
                    rows.append(f"| &nbsp;&nbsp;`{mod.name}/` | {_first_sentence(mod / '__init__.py')} |")
                    for sub in sorted(mod.glob("*.py")):
                        if sub.name != "__init__.py":
                            rows.append(f"| &nbsp;&nbsp;&nbsp;&nbsp;`{sub.name}` | {_first_sentence(sub)} |")
                elif mod.name != "__init__.py":
                    rows.append(f"| &nbsp;&nbsp;`{mod.name}` | {_first_sentence(mod)} |")
        else:
            rows.append(f"| `study/{name}` | {_first_sentence(p)} |")
    return "\n".join(rows)


def render(text: str) -> str:
    """``text`` with the table between the markers made anew."""
    a, b = text.index(BEGIN) + len(BEGIN), text.index(END)
    return text[:a] + "\n" + table() + "\n" + text[b:]


if __name__ == "__main__":
    path = MAP
    old = path.read_text()
    new = render(old)
    if "--check" in sys.argv:
        sys.exit(0 if new == old else 1)
    path.write_text(new)
