"""The unit of replication is the geometry (issue 53 item 1): the seeds of one object position (scene, object) are
copies for every geometric column, so every statistic over cases — the median's interval, the paired Wilcoxon
test, the smallest detectable difference, the per-case separations — counts distinct geometries, and the tables say
where seeds were pooled (study/report/geometry.py)."""

import math
from pathlib import Path

import numpy as np
import pytest

from study.report import geometry, power, summary

REPORTS = Path(__file__).resolve().parents[2] / "reports"
#: columns that the seed does not change (the exact hits, the searches): what names a geometry independently of
#: the case ids
GEOMETRIC = ("object_x", "object_y", "object_z", "n_rays", "wrong_fraction", "angle_median_deg", "dist_p95")


def _seeded(n_geo=3, n_seeds=4, rng_seed=0):
    """n_geo geometries × n_seeds seeds (ids ``g<i>``, ``g<i>-s<k>``, as a figure's config names them): the
    geometric columns the same at every seed, the image error drawn anew per seed; 'best' is wrong less than
    'other' in every geometry, by far more than its rays' intervals."""
    rng = np.random.default_rng(rng_seed)
    rows = []
    for k in range(n_seeds):
        for i in range(n_geo):
            for lab, wrong in (("best", 0.01 + 0.001 * i), ("other", 0.2 + 0.01 * i)):
                rows.append(
                    {
                        "case": f"fig-g{i}" + (f"-s{k}" if k else ""),
                        "label": lab,
                        "method": lab,
                        "lookups_per_ray": 1.0 if lab == "best" else 2.0,
                        "object_x": float(i),
                        "wrong_fraction": wrong,
                        "wrong_fraction_texel_lo": wrong * 0.9,
                        "wrong_fraction_texel_hi": wrong * 1.1,
                        "rmse_truth_debiased": 0.1 + (lab == "other") * 0.05 + rng.normal(0, 0.01),
                        "n_rays": 10_000.0,
                        "occluded_fraction": 0.0,
                    }
                )
    return rows


def test_over_case_statistics_count_geometries_not_seeds():
    """3 geometries × 4 seeds: 3 cases everywhere (12 before the fix: 'best' lower in 12 of 12, p = 0.00049,
    where 3 geometries cannot give less than p = 0.25), and the seeds said."""
    tab = _seeded()
    rows = {r["method"]: r for r in summary.interval_rows({"t": tab})}
    assert rows["best"]["cases"] == 3 and rows["best"]["seeds"] == 4, rows["best"]
    assert rows["other"]["p_vs_best"] >= 0.25 and math.isinf(rows["other"]["mdd_vs_best"]), rows["other"]
    assert rows["other"]["worse_cases"] == 3
    assert summary.separated(tab, "other", "best") == (0, 3, 3)
    assert summary.versus(tab, "best", "other", "wrong_fraction")["n"] == 3
    rank = summary.ranking(tab, "wrong_fraction")
    prow = power.row("t", tab, rank)
    assert prow["cases"] == 3 and prow["seeds"] == 4 and math.isinf(prow["mdd_cases_sd"])
    assert "(distinct geometries, 4 seeds each pooled)" in power.sentence(prow)
    s = summary.table_sentence("t", tab)
    assert "(3 cases (distinct geometries; 4 seeds each pooled)" in s and "fewer in 3 of 3 cases" in s, s
    assert "3 cases are too few for any difference to be significant" in s


def test_pooled_rows_average_the_seeds_and_pool_to_themselves():
    tab = _seeded()
    pooled = geometry.pooled(tab)
    assert len(pooled) == 6 and {r["case"] for r in pooled} == {"fig-g0", "fig-g1", "fig-g2"}
    for r in pooled:
        mine = [x for x in tab if x["label"] == r["label"] and x["case"].startswith(r["case"])]
        mine = [x for x in mine if geometry.SEED_SUFFIX.sub("", x["case"]) == r["case"]]
        assert len(mine) == 4 == r["seeds"]
        assert r["rmse_truth_debiased"] == pytest.approx(np.mean([x["rmse_truth_debiased"] for x in mine]))
        assert r["wrong_fraction"] == mine[0]["wrong_fraction"]
    assert geometry.pooled(pooled) is pooled
    unseeded = [r for r in tab if "-s" not in r["case"]]
    assert geometry.pooled(unseeded) is unseeded and geometry.seeds_per_geometry(unseeded) == 1


def test_a_sweeps_seed_axis_is_pooled_by_its_other_axes():
    rows = [
        {"case": f"c{i}", "label": "a", "axis:render.seed": s, "axis:object.center": p, "wrong_fraction": 0.1}
        for i, (p, s) in enumerate([(p, s) for s in (0, 1) for p in ("[0, 1, 0]", "[1, 1, 0]")])
    ]
    assert geometry.geometry_ids(rows) == {"c0": "c0", "c1": "c1", "c2": "c0", "c3": "c1"}


def _geometries(tab: list[dict]) -> int:
    """Distinct geometries of a table by its geometric columns alone (not its case ids)."""
    by: dict[str, list] = {}
    for r in tab:
        by.setdefault(r["case"], []).append(
            (r["label"], *(round(float(r.get(c, math.nan)), 12) for c in GEOMETRIC if c in r))
        )
    return len({tuple(sorted(v, key=str)) for v in by.values()})


def test_no_committed_table_counts_more_cases_than_geometries():
    """Every committed table's over-case statistics (the summary's interval rows and power rows) count at most its
    distinct geometries, named by the geometric columns alone. Before the fix fig_cornell counted 12 cases of 2."""
    from study.report.check import read_table

    tables = {
        d.name: read_table(d / f)
        for f in ("metrics.csv", "results.csv")
        for d in sorted(REPORTS.glob("*"))
        if (d / f).is_file()
    }
    tables = {n: t for n, t in tables.items() if t and "wrong_fraction" in t[0]}
    assert len(tables) >= 10
    rows = summary.interval_rows(tables)
    assert len({r["table"] for r in rows}) >= 10
    for name, tab in tables.items():
        n = _geometries(tab)
        counted = {r["cases"] for r in rows if r["table"] == name}
        assert max(counted, default=0) <= n, (name, counted, n)
        if rank := summary.ranking(tab, "wrong_fraction"):  # fig_hitcache holds exact queries alone
            assert power.row(name, tab, rank)["cases"] <= n, name
