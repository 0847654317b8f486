"""The glossy figure's tables (:func:`study.outputs.glossy.write_split`), printed as Markdown and written beside it
again (``split.csv``, ``glossy.md``). ``study figure fig_glossy`` (kind ``glossy``) writes them itself; this
script remakes them from a finished figure folder.

    PYTHONPATH=. .venv/bin/python scripts/glossy_split.py [reports/fig_glossy]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from study.outputs import glossy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fig", nargs="?", default="reports/fig_glossy", type=Path)
    print(glossy.write_split(ap.parse_args().fig))


if __name__ == "__main__":
    main()
