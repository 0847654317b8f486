"""The README's figure: one case of Figure 5 (reports/fig5/fig5.png), cut into a grid readable at README width.

    .venv/bin/python scripts/readme_figure.py     # writes docs/images/fig5-case.png (deterministic; committed)

Top row: the Mitsuba render and the images of classical, localized and layered; below each method its per-pixel
outcome, and below the render the pixels whose exact hit the reference point cannot see. The panels are found by
their black frames in the committed figure, so a regenerated fig5.png with the same layout makes the same cut.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "reports" / "fig5" / "fig5.png"
OUT = ROOT / "docs" / "images" / "fig5-case.png"
#: panel columns of fig5.png (config grid: classical, localized, layered; then Mitsuba, 3 angle errors,
#: 3 outcomes, hidden): top row Mitsuba + the three images, bottom row hidden + the three outcomes
TOP, BOTTOM = [3, 0, 1, 2], [10, 7, 8, 9]
CASE = 0  # the first case: right above the column, its top fills the lower half of the reflection
PAD = 4


def _runs(line: np.ndarray, min_len: int) -> list[tuple[int, int]]:
    """(first, last) index of each run of True in ``line`` at least ``min_len`` long."""
    d = np.diff(np.concatenate([[0], line.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    return [(a, b) for a, b in zip(starts.tolist(), ends.tolist(), strict=True) if b - a + 1 >= min_len]


def panels(img: np.ndarray) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """The frames of the grid's panels: their x ranges (from the first row's top edge) and y ranges."""
    dark = img.sum(axis=2) < 150
    lines = np.flatnonzero(dark.sum(axis=1) >= dark.shape[1] // 2)  # the frames' top and bottom edges
    ys = list(zip(lines[0::2].tolist(), lines[1::2].tolist(), strict=False))
    xs = _runs(dark[ys[0][0]], 100)  # each panel's top edge is one dark run; the colour bar's is short
    return xs, ys


def main() -> None:
    img = np.asarray(Image.open(SRC).convert("RGB"))
    xs, ys = panels(img)
    assert len(xs) == 11 and len(ys) == 3, f"unexpected layout of {SRC}: {len(xs)} columns, {len(ys)} rows"
    y0, y1 = ys[CASE]
    w = xs[0][1] - xs[0][0] + 1
    head = int(0.2 * w)  # the two-line column titles above each frame

    def tile(col: int) -> np.ndarray:
        x0, x1 = xs[col]
        cx = (x0 + x1) // 2
        half = (x1 - x0) // 2 + PAD  # titles may be a little wider than the frame
        return img[y0 - head : y1 + 1, cx - half : cx + half + 1]

    rows = [np.concatenate([tile(c) for c in cols], axis=1) for cols in (TOP, BOTTOM)]
    below = img[ys[-1][1] + 3 :]  # the outcome legend under the last row
    ink = np.flatnonzero((below.sum(axis=2) < 600).any(axis=1))
    legend = below[ink[0] - 2 : ink[-1] + 3]
    lx = np.flatnonzero((legend.sum(axis=2) < 600).any(axis=0))
    legend = legend[:, lx[0] - 2 : lx[-1] + 3]
    width = rows[0].shape[1]
    if legend.shape[1] > width:
        legend = np.asarray(
            Image.fromarray(legend).resize((width, round(legend.shape[0] * width / legend.shape[1])))
        )
    strip = np.full((legend.shape[0], width, 3), 255, np.uint8)
    off = (width - legend.shape[1]) // 2
    strip[:, off : off + legend.shape[1]] = legend
    OUT.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.concatenate([*rows, strip], axis=0)).save(OUT, optimize=True)
    print(f"wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
