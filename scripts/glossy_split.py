"""The glossy figure's tables, printed as Markdown and written beside it (``split.csv``, ``glossy.md``): the error
of every method against the lobe's truth per α and object position (noise-debiased RMSE with its 95 % interval
over pixels), the split of the engines' default into prefiltering, localization, remainder, visibility and
noise (study.outputs.glossy), and the smallest α from which on the localization error stays below the
prefiltering error.

    PYTHONPATH=. .venv/bin/python scripts/glossy_split.py [reports/fig_glossy]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from study.io import atomic_write
from study.outputs import glossy
from study.tables import markdown


def fmt(v, lo, hi) -> str:
    return f"{v:.3f} [{lo:.3f}, {hi:.3f}]"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fig", nargs="?", default="reports/fig_glossy", type=Path)
    a = ap.parse_args()
    m = pd.read_csv(a.fig / "metrics.csv")
    m = m[m.method != "truth_at_hit"].copy()
    m["where"] = m.apply(
        lambda r: f"α={r.object_alpha:g} @({r.object_x:g}, {r.object_y:g}, {r.object_z:g})", 1
    )
    m["cell"] = [
        fmt(v, lo, hi)
        for v, lo, hi in zip(m.rmse_truth_debiased, m.rmse_truth_debiased_lo, m.rmse_truth_debiased_hi)
    ]
    by_method = m.pivot(index="label", columns="where", values="cell")
    s = glossy.split_table(a.fig)
    parts = ["total", "prefiltering", "localization", "remainder", "visibility"]
    split = pd.DataFrame(
        {
            "case": s.case,
            "α": s.alpha,
            **{p: [fmt(r[p], r[f"{p}_lo"], r[f"{p}_hi"]) for _, r in s.iterrows()] for p in parts},
            "hidden px": s.visibility_pixels,
            "noise": s.noise.round(3),
        }
    )
    cross = glossy.crossover(s)
    text = "\n\n".join(
        [
            "## Error against the lobe's truth (noise-debiased RMSE [95 % interval over pixels])",
            markdown(by_method.reset_index().to_dict("records"), ["label", *by_method.columns]),
            "## The split of `prefiltered` (RMSE [95 % interval over pixels])",
            markdown(split.to_dict("records"), list(split.columns)),
            "## From which α on localization errs less than prefiltering",
            "\n".join(
                f"- object at {pos}: " + (f"α ≥ {a_:g}" if a_ == a_ else "at no α of the table")
                for pos, a_ in cross.items()
            ),
        ]
    )
    print(text)
    s.to_csv(a.fig / "split.csv", index=False)
    atomic_write(a.fig / "glossy.md", text + "\n")


if __name__ == "__main__":
    main()
