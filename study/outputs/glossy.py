"""Glossy reflections: the split of the engines' error into its parts, from a glossy figure's outputs.

Per case (an ``object.alpha`` × object position of ``configs/fig_glossy.toml``), over the object's pixels
(``mask``), each part is an RMSE between two images of the case's EXR, with a 95 % interval over the spatially
correlated pixels (:func:`study.stats.spatial.mean_intervals` on the per-pixel squared errors, the interval's ends
square-rooted):

==============  =======================================  ===================================================
part            images                                   what differs
==============  =======================================  ===================================================
total           ``prefiltered`` vs ``truth_at_hit``      everything the engines' default gets wrong
prefiltering    ``prefiltered`` vs ``stochastic(…,       the split sum's v = n and the mip chain, at the same
                localize=False)``                        (classical) lookups from the reference point
localization    ``stochastic(…, localize=False)`` vs     looking the lobe up from the reference point instead of
                the localized ``stochastic`` (most N)    from the shading point
remainder       the localized ``stochastic`` vs          what the impostor cannot hold (points hidden from the
                ``truth_at_hit``                         reference point, texels) and the sampling noise
visibility      the remainder, over the pixels with      the same, where exact hits are hidden from o
                hidden hits only
noise           the truth's own noise                    ``truth_noise_rmse`` of the metrics table
==============  =======================================  ===================================================

The stochastic images carry their own Monte Carlo noise: at N = 16 samples it adds to prefiltering and
localization alike (stated, not removed).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from study.io import atomic_write, file_stem, read_exr_layers
from study.stats import LEVEL
from study.stats.spatial import mean_intervals
from study.tables import markdown

#: (part, first image, second image, pixels): image names are file stems of labels (``study.io.file_stem``)
PARTS = (
    ("total", "prefiltered", "truth_at_hit", "all"),
    ("prefiltering", "prefiltered", "unlocalized", "all"),
    ("localization", "unlocalized", "localized", "all"),
    ("remainder", "localized", "truth_at_hit", "all"),
    ("visibility", "localized", "truth_at_hit", "hidden"),
)


def _stochastic(layers: dict, localize: bool) -> str:
    """The stochastic image with the most samples, localized or not."""
    best, most = None, -1
    for name in layers:
        m = re.fullmatch(r"stochastic-samples-(\d+)(-localize-False)?", name)
        if m and bool(m.group(2)) != localize and int(m.group(1)) > most:
            best, most = name, int(m.group(1))
    if best is None:
        raise KeyError(f"no {'localized' if localize else 'unlocalized'} stochastic image")
    return best


def case_split(exr: Path) -> dict:
    """The parts (module docstring) of one case's EXR: {part: rmse, part_lo, part_hi, part_pixels}."""
    layers = read_exr_layers(exr)
    names = {
        "prefiltered": file_stem("prefiltered"),
        "truth_at_hit": "truth_at_hit",
        "unlocalized": _stochastic(layers, localize=False),
        "localized": _stochastic(layers, localize=True),
    }
    mask = layers["mask"][..., 0] > 0.5
    hidden = mask & (layers["hidden"][..., 0] > 0)
    out = {}
    for part, a, b, where in PARTS:
        px = mask if where == "all" else hidden
        sq = np.mean((layers[names[a]] - layers[names[b]]) ** 2, axis=-1)[px]
        ((lo, hi),) = mean_intervals([sq], px, LEVEL)[0] if sq.size else [(np.nan, np.nan)]
        out[part] = float(np.sqrt(sq.mean())) if sq.size else np.nan
        out[f"{part}_lo"], out[f"{part}_hi"] = float(np.sqrt(lo)), float(np.sqrt(hi))
        out[f"{part}_pixels"] = int(px.sum())
    return out


def split_table(fig_dir: str | Path) -> pd.DataFrame:
    """One row per case of a glossy figure's outputs (``metrics.csv`` and ``exr/``): its α and object position,
    the parts with their intervals and the truth's noise."""
    fig_dir = Path(fig_dir)
    metrics = pd.read_csv(fig_dir / "metrics.csv")
    rows = []
    for case, g in metrics.groupby("case", sort=False):
        truth = g[g.method == "truth_at_hit"].iloc[0]
        rows.append(
            {
                "case": case,
                "alpha": float(g["object_alpha"].iloc[0]) if "object_alpha" in g else np.nan,
                "object": tuple(float(truth[f"object_{c}"]) for c in "xyz"),
                **case_split(fig_dir / "exr" / f"{case}.exr"),
                "noise": float(truth["truth_noise_rmse"]),
            }
        )
    return pd.DataFrame(rows)


def crossover(table: pd.DataFrame) -> dict:
    """Per object position: the smallest α from which on the localization error stays below the prefiltering
    error (NaN: at no α of the table)."""
    out = {}
    for pos, g in table.sort_values("alpha").groupby("object", sort=False):
        below = (g["localization"] < g["prefiltering"]).to_numpy()
        first = next((i for i in range(len(below)) if below[i:].all()), None)
        out[pos] = float(g["alpha"].iloc[first]) if first is not None else np.nan
    return out


def _cell(v, lo, hi) -> str:
    return f"{v:.3f} [{lo:.3f}, {hi:.3f}]"


def write_split(fig_dir: Path) -> str:
    """A glossy figure's tables, written beside it (``split.csv``, ``glossy.md``) and returned as Markdown: the
    error of every method against the lobe's truth per α and object position (noise-debiased RMSE with its 95 %
    interval over pixels), the split of the engines' default (:func:`split_table`), and from which α on the
    localization error stays below the prefiltering error (:func:`crossover`)."""
    m = pd.read_csv(fig_dir / "metrics.csv")
    m = m[m.method != "truth_at_hit"].copy()
    seed = m.case.astype(str).str.extract(r"-s(\d+)$", expand=False)  # a figure's later seeds (study.harness)
    m["where"] = m.apply(
        lambda r: f"α={r.object_alpha:g} @({r.object_x:g}, {r.object_y:g}, {r.object_z:g})", 1
    ) + seed.map(lambda k: f" seed {k}" if isinstance(k, str) else "")
    m["cell"] = [
        _cell(v, lo, hi)
        for v, lo, hi in zip(m.rmse_truth_debiased, m.rmse_truth_debiased_lo, m.rmse_truth_debiased_hi)
    ]
    by_method = m.pivot(index="label", columns="where", values="cell")
    s = split_table(fig_dir)
    parts = ["total", "prefiltering", "localization", "remainder", "visibility"]
    split = pd.DataFrame(
        {
            "case": s.case,
            "α": s.alpha,
            **{p: [_cell(r[p], r[f"{p}_lo"], r[f"{p}_hi"]) for _, r in s.iterrows()] for p in parts},
            "hidden px": s.visibility_pixels,
            "noise": s.noise.round(3),
        }
    )
    cross = crossover(s)
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
    s.to_csv(fig_dir / "split.csv", index=False)
    atomic_write(fig_dir / "glossy.md", text + "\n")
    return text
