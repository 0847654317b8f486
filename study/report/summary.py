"""The report's headline: which method to use where, and how sure the tables let us be.

Everything here reads results tables (one row per case × method) and nothing else. Per table:

* **the best** method for a metric is the one with the lowest median over the table's cases; its median comes
  with an order-statistic interval over the cases (their range below 10 cases) and its worst case (a median
  hides failures);
* **the runner-up** is compared with it over the same cases (:func:`study.stats.paired`: Wilcoxon
  signed-rank, two-sided, with the count of cases each wins): "significant at 1 %/5 %" or "no significant
  difference"; below 6 cases no difference can reach 5 % (:func:`study.stats.min_p`), and the headline
  says so;
* per case, two wrong fractions are **separated** when their calibrated 95 % intervals over the rays do not
  overlap (:func:`study.report.intervals.bounds`: the ``_lo``/``_hi`` the declared column table names);
* **the recommendation** is the cheapest method (cube-map lookups per ray) that is *as good as the best* in
  wrong hits: separated above the best's in no case, and not significantly worse over the cases (p ≥ 5 %).

Image error is ranked on the relative column ``relmse_truth_exposed`` (relMSE after exposure, ε = 0.01:
:mod:`study.measure.exposure`), which means the same in a dark scene as in a bright one, with the absolute
noise-debiased RMSE told beside it; tables written before that column rank on the RMSE. Ranking by RMSE is also
redone on ``rmse_truth_debiased_trim`` (the worst 0.1 % of pixels left out); a changed winner is flagged.
"""

from __future__ import annotations

import math

import numpy as np

from study import columns, stats
from study import methods as registry
from study.measure import case_columns
from study.outputs.markup import code, md_esc
from study.report import geometry, power, significance, table_notes
from study.report.intervals import separated
from study.report.power import SIGNIFICANCE, WRONG
from study.tables import REFERENCE_ROWS, fmt_number

IMAGE = "rmse_truth_debiased"
#: The image error the summary ranks on where a table has it: relative, the same for a scene × k (module docstring).
RELATIVE = "relmse_truth_exposed"
COST = "lookups_per_ray"


def _pct(v: float) -> str:
    return "–" if not v == v else f"{100 * v:.3g} %"


def _cost(v: float) -> str:
    return f"{v:.0f}" if v >= 10 else fmt_number(v)


def _span(costs) -> str:
    lo, hi = min(costs), max(costs)
    return _cost(lo) if lo == hi else f"{_cost(lo)}–{_cost(hi)}"


def _per_ray(*costs) -> str:
    """'1 lookup/ray', '13 lookups/ray', '428–1047 lookups/ray'."""
    return f"{_span(costs)} lookup{'' if set(costs) == {1} else 's'}/ray"


def _labels(tab: list[dict]) -> list[str]:
    """The stand-ins: no reference, no row that traces the rays (traced, hit_cache: see ``study pareto``)."""
    exact = {r["label"] for r in tab if getattr(registry.REGISTRY.get(r.get("method")), "bench_query", None)}
    exact |= set(REFERENCE_ROWS)
    return [lab for lab in dict.fromkeys(r["label"] for r in tab) if lab not in exact]


def _values(tab: list[dict], label: str, col: str, cases: list[str]) -> np.ndarray:
    by = {r["case"]: r.get(col, math.nan) for r in tab if r["label"] == label}
    return np.array([float(by.get(c, math.nan)) for c in cases], float)


def interval_words(r: dict) -> str:
    """How an interval over cases is told: "95 % CI over cases" or "range over n = 3"."""
    return "95 % CI over cases" if r.get("kind", "ci") == "ci" else f"range over n = {r['n']}:"


def ranking(tab: list[dict], col: str) -> list[dict]:
    """Methods by their median over the cases of ``col`` (lowest first; ties to the lower worst case, then to the
    cheaper), each with ``median``, ``lo``/``hi``, ``kind`` (:func:`study.stats.case_interval`), ``max``,
    ``worst`` (its case), ``n`` (distinct geometries, :func:`study.report.geometry.pooled`) and ``cost`` (median
    lookups per ray). A backend-sensitive column (its value hangs on float32 arithmetic) ranks nothing: empty."""
    if getattr(columns.declared(col), "backend_sensitive", False):
        return []
    tab = geometry.pooled(tab)
    cases = list(dict.fromkeys(r["case"] for r in tab))
    out = []
    for lab in _labels(tab):
        v = _values(tab, lab, col, cases)
        med, lo, hi, n, kind = stats.case_interval(v)
        if n == 0:
            continue
        i = int(np.nanargmax(v))
        cost = float(np.nanmedian(_values(tab, lab, COST, cases)))
        out.append(
            {
                "label": lab,
                "median": med,
                "lo": lo,
                "hi": hi,
                "kind": kind,
                "max": v[i],
                "worst": cases[i],
                "n": n,
                "cost": cost,
            }
        )
    return sorted(out, key=lambda r: (r["median"], r["max"], r["cost"] if r["cost"] == r["cost"] else np.inf))


def swapped_pairs(a: list[dict], b: list[dict]) -> tuple[int, int]:
    """(pairs of methods ordered differently, pairs compared) by two rankings of :func:`ranking`."""
    pa, pb = {r["label"]: i for i, r in enumerate(a)}, {r["label"]: i for i, r in enumerate(b)}
    common = [lab for lab in pa if lab in pb]
    pairs = [(x, y) for i, x in enumerate(common) for y in common[i + 1 :]]
    return sum((pa[x] < pa[y]) != (pb[x] < pb[y]) for x, y in pairs), len(pairs)


def cost_front(rank: list[dict]) -> list[dict]:
    """The rows of :func:`ranking` that no cheaper (or equally cheap) row matches in median, cheapest first."""
    front, low = [], math.inf
    for r in sorted((r for r in rank if r["cost"] == r["cost"]), key=lambda r: (r["cost"], r["median"])):
        if r["median"] < low:
            front.append(r)
            low = r["median"]
    return front


def versus(tab: list[dict], a: str, b: str, col: str) -> dict:
    """Paired comparison of methods a and b over the table's geometries (:func:`study.stats.paired`; the
    seeds of a geometry pooled, :func:`study.report.geometry.pooled`)."""
    tab = geometry.pooled(tab)
    cases = list(dict.fromkeys(r["case"] for r in tab))
    return stats.paired(_values(tab, a, col, cases), _values(tab, b, col, cases))


def _verdict(cmp: dict) -> str:
    n = cmp["n"]
    if n and stats.min_p(n) >= SIGNIFICANCE:
        return f"{n} cases are too few for any difference to be significant at {SIGNIFICANCE:.0%}"
    return stats.significance(cmp["p"], SIGNIFICANCE)


def recommend(tab: list[dict]) -> tuple[dict, dict] | None:
    """(best, cheapest as good) in wrong hits (module docstring), as rows of :func:`ranking`."""
    rank = ranking(tab, WRONG)
    if not rank:
        return None
    best = rank[0]
    for r in sorted(rank, key=lambda r: (r["cost"], r["median"])):
        if r is best:
            return best, r
        _, above, _ = separated(tab, r["label"], best["label"])
        cmp = versus(tab, r["label"], best["label"], WRONG)
        if above == 0 and not cmp["p"] < SIGNIFICANCE:
            return best, r
    return best, best


def _hidden(tab: list[dict]) -> float:
    v = [r.get("occluded_fraction", math.nan) for r in tab if r["label"] not in REFERENCE_ROWS]
    v = np.array(v, float)
    return float(np.nanmedian(v)) if np.isfinite(v).any() else math.nan


def table_sentence(name: str, tab: list[dict]) -> str | None:
    """One table's verdict in words: best and recommended method for wrong hits, how sure, and the image-error
    winner against its runner-up (and whether leaving out the worst pixels changes it)."""
    seeds = geometry.seeds_per_geometry(tab)
    tab = geometry.pooled(tab)
    rec = recommend(tab)
    if rec is None:
        return None
    best, use = rec
    n = best["n"]
    rank = ranking(tab, WRONG)
    parts = [
        f"fewest wrong hits: {code(best['label'])}, median {_pct(best['median'])} ({interval_words(best)} "
        f"{_pct(best['lo'])}–{_pct(best['hi'])}; worst case {_pct(best['max'])}, {md_esc(best['worst'])})"
    ]
    if len(rank) > 1:
        ru = rank[1]
        cmp = versus(tab, best["label"], ru["label"], WRONG)
        below, _, nc = separated(tab, best["label"], ru["label"])
        parts.append(
            f"vs the runner-up {code(ru['label'])} ({_pct(ru['median'])}): fewer in {cmp['a_better']} of "
            f"{cmp['n']} cases ({cmp['ties']} tied), {_verdict(cmp)}; per case, the rays' 95 % intervals "
            f"separate the two in {below} of {nc}"
        )
    if use is not best:
        parts.append(
            f"as good and cheaper: {code(use['label'])} at {_per_ray(use['cost'])} (vs {_cost(best['cost'])}),"
            f" median {_pct(use['median'])}, worst {_pct(use['max'])}"
        )
    else:
        cheap = min(rank, key=lambda r: (r["cost"], r["median"]))
        if cheap["label"] != best["label"]:
            _, above, nc = separated(tab, cheap["label"], best["label"])
            parts.append(
                f"no cheaper method is as good: the cheapest, {code(cheap['label'])} ({_per_ray(cheap['cost'])}), "
                f"has median {_pct(cheap['median'])} and more wrong hits beyond its rays' "
                f"uncertainty in {above} of {nc} cases"
            )
    fixed = {r["label"]: r for r in ranking(tab, "wrong_fraction_1cm")}
    if best["label"] in fixed:  # tables written with the fixed-tolerance columns
        f = fixed[best["label"]]
        parts.append(
            f"at a fixed 1 cm tolerance {code(best['label'])} is wrong on {_pct(f['median'])} (median; worst "
            f"{_pct(f['max'])})"
            + (f", {code(use['label'])} on {_pct(fixed[use['label']]['median'])}" if use is not best else "")
        )
    front = cost_front(rank)
    if len(front) > 1:
        parts.append(
            "cost → wrong hits (medians), each step buying fewer: "
            + " → ".join(f"{code(r['label'])} {_cost(r['cost'])}: {_pct(r['median'])}" for r in front)
        )
    if text := _image_text(tab):
        parts.append(text)
    hid = _hidden(tab)
    where = "nothing hidden from the reference point" if hid == 0 else f"median hidden rays {_pct(hid)}"
    pool = f" (distinct geometries; {seeds} seeds each pooled)" if seeds > 1 else ""
    return f"**{md_esc(name)}** ({n} case{'s' if n != 1 else ''}{pool}, {where}): " + "; ".join(parts) + "."


def image_column(tab: list[dict]) -> str:
    """The column image error is ranked on: :data:`RELATIVE` where the table has it, else :data:`IMAGE`."""
    have = (v for r in tab if isinstance(v := r.get(RELATIVE), int | float))
    return RELATIVE if any(math.isfinite(v) for v in have) else IMAGE


def _image_text(tab: list[dict]) -> str | None:
    """The image-error winner against its runner-up, on :func:`image_column`, the absolute RMSE beside it, and
    whether leaving out the worst 0.1 % of pixels changes the RMSE's order."""
    col = image_column(tab)
    img, absolute = ranking(tab, col), {r["label"]: r for r in ranking(tab, IMAGE)}
    if len(img) < 2:
        return None
    a, b = img[0], img[1]
    cmp = versus(tab, a["label"], b["label"], col)
    what = "relMSE after exposure, ε = 0.01" if col == RELATIVE else "RMSE vs truth, noise-debiased"
    text = (
        f"lowest image error ({what}): {code(a['label'])} {fmt_number(a['median'])} vs "
        f"{code(b['label'])} {fmt_number(b['median'])}, lower in {cmp['a_better']} of {cmp['n']} cases, "
        f"{_verdict(cmp)}"
    )
    if col == RELATIVE and a["label"] in absolute and b["label"] in absolute:
        ra, rb = absolute[a["label"]]["median"], absolute[b["label"]]["median"]
        text += f" (absolute RMSE, noise-debiased: {fmt_number(ra)} vs {fmt_number(rb)})"
        if rb < ra:
            text += (
                f"; **by absolute RMSE {code(b['label'])} is lower** (absolute errors scale with brightness)"
            )
    abs_rank, trim = ranking(tab, IMAGE), ranking(tab, f"{IMAGE}_trim")
    by = "" if col == IMAGE else " by RMSE"  # tables before RELATIVE: the words as they were
    if trim and abs_rank and trim[0]["label"] != abs_rank[0]["label"]:
        text += f"; **without the worst 0.1 % of pixels the winner{by} is {code(trim[0]['label'])}**"
    swaps, pairs = swapped_pairs(abs_rank, trim)
    if swaps:
        text += f"; without them {swaps} of {pairs} pairs of methods swap places{by}"
    return text


def headline(tables: dict[str, list[dict]]) -> str | None:
    """The plain-words headline over all tables: which method to use where, and how sure
    (:func:`study.report.significance.how_sure` of :func:`significance_counts`)."""
    recs = {name: recommend(tab) for name, tab in tables.items()}
    recs = {k: v for k, v in recs.items() if v is not None}
    if not recs:
        return None
    groups: dict[str, list[str]] = {}
    for name, (_, use) in recs.items():
        groups.setdefault(use["label"], []).append(name)
    uses = "; ".join(
        f"{code(lab)} ({_per_ray(*[recs[n][1]['cost'] for n in names])}) in {', '.join(md_esc(n) for n in names)}"
        for lab, names in sorted(groups.items(), key=lambda g: recs[g[1][0]][1]["cost"])
    )
    where = ""
    clear = [n for n in recs if _hidden(tables[n]) == 0]
    if clear and len(clear) < len(recs):
        cost = {n: recs[n][1]["cost"] for n in recs}
        hid = [cost[n] for n in recs if n not in clear]
        where = (
            f" Where nothing is hidden from the reference point ({', '.join(clear)}) that method costs "
            f"{_per_ray(*[cost[n] for n in clear])}; where exact hits hide from it (the other {len(hid)} "
            f"tables), {_span(hid)}."
        )
    return (
        f"**Use**, per table, the cheapest method whose wrong-hit fraction is indistinguishable from the best's "
        f"(no case where its rays' 95 % interval lies above the best's, and no significant difference over the "
        f"cases): {uses}.{where} **How sure:** {significance.how_sure(significance_counts(tables))}"
    )


def significance_counts(tables: dict[str, list[dict]]) -> list[dict]:
    """Per table, counted over distinct geometries (:func:`study.report.geometry.pooled`): ``cases`` (geometries),
    ``seeds`` (seeds pooled per geometry), the best and the runner-up in wrong hits with the Wilcoxon p over the
    geometries (``p``, ``best``, ``runner_up``), and the same by image error (``image_p``, on
    :func:`study.report.image_column`); NaN where a table has one method."""
    out = []
    for name, tab in tables.items():
        seeds = geometry.seeds_per_geometry(tab)
        tab = geometry.pooled(tab)
        rank = ranking(tab, WRONG)
        if not rank:
            continue
        row = {"table": name, "cases": rank[0]["n"], "seeds": seeds, "best": rank[0]["label"]}
        row |= {"runner_up": "", "p": math.nan, "image_p": math.nan}
        if len(rank) > 1:
            row["runner_up"] = rank[1]["label"]
            row["p"] = versus(tab, rank[0]["label"], rank[1]["label"], WRONG)["p"]
        img = ranking(tab, col := image_column(tab))
        if len(img) > 1:
            row["image_p"] = versus(tab, img[0]["label"], img[1]["label"], col)["p"]
        out.append(row)
    return out


#: The columns of :func:`interval_rows`.
INTERVAL_COLUMNS = [
    "table",
    "method",
    "cases",
    "seeds",
    "lookups",
    "wrong",
    "wrong_lo",
    "wrong_hi",
    "interval",
    "wrong_max",
    "worse_cases",
    "p_vs_best",
    "mdd_vs_best",
    "rmse",
    "rmse_lo",
    "rmse_hi",
    "relmse",
    "relmse_lo",
    "relmse_hi",
]


_RELMSE_KEYS = (("", "median"), ("_lo", "lo"), ("_hi", "hi"))


def interval_rows(tables: dict[str, list[dict]]) -> list[dict]:
    """Per table and method: the median over cases of the wrong fraction and of the debiased RMSE with their
    intervals over the cases (``_lo``/``_hi``: the median's 95 % CI, or the cases' range below
    ``stats.MIN_CASES_CI`` cases; ``interval`` says which), the worst case (``wrong_max``), the cases where the
    method's wrong fraction lies above the best's beyond both rays' intervals (``worse_cases``), the Wilcoxon
    p-value of its wrong fractions against the best's over the same cases (``p_vs_best``) and the smallest
    difference from the best's that those cases could detect (``mdd_vs_best``,
    :func:`study.report.power.detectable`; inf below 6
    cases); ``relmse``/``_lo``/``_hi`` the same for :data:`RELATIVE` (NaN for tables without it)."""
    out = []
    for name, tab in tables.items():
        seeds = geometry.seeds_per_geometry(tab)
        tab = geometry.pooled(tab)
        rank = ranking(tab, WRONG)
        if not rank:
            continue
        best = rank[0]["label"]
        img = {r["label"]: r for r in ranking(tab, IMAGE)}
        rel = {r["label"]: r for r in ranking(tab, RELATIVE)}
        for r in rank:
            i = img.get(r["label"], {})
            same = r["label"] == best
            out.append(
                {
                    "table": name,
                    "method": r["label"],
                    "cases": r["n"],
                    "seeds": seeds,
                    "lookups": r["cost"],
                    "wrong": r["median"],
                    "wrong_lo": r["lo"],
                    "wrong_hi": r["hi"],
                    "interval": "95 % CI" if r["kind"] == "ci" else "range",  # of wrong_lo/hi and rmse_lo/hi
                    "wrong_max": r["max"],
                    "worse_cases": 0 if same else separated(tab, r["label"], best)[1],
                    "p_vs_best": math.nan if same else versus(tab, r["label"], best, WRONG)["p"],
                    "mdd_vs_best": math.nan if same else power.detectable(tab, r["label"], best, WRONG),
                    "rmse": i.get("median", math.nan),
                    "rmse_lo": i.get("lo", math.nan),
                    "rmse_hi": i.get("hi", math.nan),
                    **{f"relmse{k}": rel.get(r["label"], {}).get(v, math.nan) for k, v in _RELMSE_KEYS},
                }
            )
    return out


def headline_tables(tables: dict[str, list[dict]]) -> dict[str, list[dict]]:
    """The tables the headline judges by wrong hits: those of mirror and glass objects (rough objects' tables,
    ``object_alpha`` > 0, are judged by their error split and claims)."""
    return {n: t for n, t in tables.items() if not any((r.get("object_alpha") or 0) > 0 for r in t)}


def readme_how_sure(tables: dict[str, list[dict]], width: int = 118) -> str:
    """The README's "How sure" bullet: :func:`how_sure` over :func:`headline_tables`, wrapped to ``width``."""
    import textwrap

    text = significance.how_sure(significance_counts(headline_tables(tables)), names=False)
    return textwrap.fill(
        f"- **How sure:** {text[0].upper()}{text[1:]}", width, subsequent_indent="  ", break_on_hyphens=False
    )


def headline_blocks(tables: dict[str, list[dict]]) -> list[tuple]:
    """The report blocks of the headline: a heading, the headline paragraph and one sentence per table. Tables of
    rough objects (``object_alpha`` > 0) are left out: a glossy method shows a lobe, not a hit, so wrong hits do
    not rank it; their error split and claims judge them (the glossy figure's section)."""
    tables = headline_tables(tables)  # each statistic below pools a geometry's seeds and says how many
    head = headline(tables)
    if head is None:
        return []
    items = [s for name, tab in tables.items() if (s := table_sentence(name, tab))]
    return [
        ("h", 2, "Summary"),
        ("p", head),
        ("list", items),
        ("p", table_notes.interval_note()),
        ("table", interval_rows(tables), INTERVAL_COLUMNS),
        *power.power_blocks(
            [power.row(name, tab, rank) for name, tab in tables.items() if (rank := ranking(tab, WRONG))]
        ),
    ]


def tolerance_curve_rows(tab: list[dict]) -> list[dict]:
    """The wrong-fraction-versus-tolerance curve per method: median over the cases of ``wrong_fraction_<tol>``
    at each fixed tolerance of :data:`study.measure.case_columns.TOLERANCES` (rows: label, tolerance_m, wrong,
    wrong_max); empty for a table written before those columns."""
    tab = geometry.pooled(tab)
    cases = list(dict.fromkeys(r["case"] for r in tab))
    out = []
    for lab in _labels(tab):
        for name, tol in case_columns.TOLERANCES.items():
            v = _values(tab, lab, f"wrong_fraction_{name}", cases)
            if np.isfinite(v).any():
                out.append(
                    {
                        "label": lab,
                        "tolerance_m": tol,
                        "wrong": float(np.nanmedian(v)),
                        "wrong_max": np.nanmax(v),
                    }
                )
    return out
