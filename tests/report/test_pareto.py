"""``study pareto``: the front on synthetic tables with known dominated points, the budget answers read off it, the
times taken from a bench table (scaled to 1080p by the ray count, the exact query pricing ``traced``), the page and
plots written, and bad options as one line."""

import csv
import math

import numpy as np
import pytest
from conftest import run_cli

from study.report import pareto

#: (label, family, cost, error): B dominates C (dearer and worse), D (as dear, worse) and E (as good, dearer);
#: A, B and F are the front; G has no error (left out).
POINTS = [
    ("A", "a", 1.0, 0.5),
    ("B", "b", 2.0, 0.2),
    ("C", "c", 3.0, 0.3),
    ("D", "d", 2.0, 0.4),
    ("E", "e", 4.0, 0.2),
    ("F", "f", 5.0, 0.0),
    ("G", "g", 0.5, math.nan),
]


def _rows():
    return [{"label": lab, "family": fam, "ms": c, "err": e} for lab, fam, c, e in POINTS]


def test_front_drops_every_dominated_point():
    front = pareto.pareto_front(_rows(), "ms", "err")
    assert [r["label"] for r in front] == ["A", "B", "F"]
    rows = _rows()  # brute force: a point is on the front iff no other is ≤ in both and < in one
    for r in rows:
        if not np.isfinite(r["err"]):
            continue
        beaten = any(
            o is not r and np.isfinite(o["err"]) and o["ms"] <= r["ms"] and o["err"] <= r["err"]
            and (o["ms"] < r["ms"] or o["err"] < r["err"])
            for o in rows
        )  # fmt: skip
        assert beaten == (r["label"] not in {f["label"] for f in front}), r["label"]


def test_budget_answers_are_the_best_point_within_the_budget():
    front = pareto.pareto_front(_rows(), "ms", "err")
    assert pareto.at_budget(front, 0.9, "ms") is None  # below the cheapest
    assert pareto.at_budget(front, 1.0, "ms")["label"] == "A"  # at its cost exactly
    assert pareto.at_budget(front, 4.9, "ms")["label"] == "B"  # E (4 ms) is dominated: never the answer
    assert pareto.at_budget(front, 100.0, "ms")["label"] == "F"


def _write(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _bench(tmp_path, tag, backend, times, exact_ms):
    """A bench table: one close-up batch (and a synthetic one with other times), methods on the frozen path."""
    rows = []
    for batch, k in (("fig4 close-up (1, 1, 1) 1024²", 1.0), ("synthetic 1048576", 10.0)):
        for lab, ms in times.items():
            rows.append(
                {
                    "batch": batch,
                    "backend": backend,
                    "path": "frozen",
                    "label": lab,
                    "ms_per_frame": ms * k,
                    "kernel_ms_per_frame": ms * k / 2,
                }
            )
        variant = "cuda_ad_rgb" if backend == "cuda" else "llvm_ad_rgb"
        for q, ms in (
            ("ray_intersect", 9 * exact_ms),
            ("ray_intersect_preliminary", exact_ms),
            ("ray_test", 0.1),
        ):
            rows.append({"batch": batch, "backend": backend, "path": q, "label": f"exact: Mitsuba {variant}",
                         "ms_per_frame": ms * k, "kernel_ms_per_frame": ms * k / 4})  # fmt: skip
    p = tmp_path / f"bench-{tag}.csv"
    _write(p, rows)
    gpu = "NVIDIA Testcard, 1.0, 10 MiB" if backend == "cuda" else "none"
    p.with_suffix(".md").write_text(
        f"# study bench ({tag})\n\nmachine: Test CPU, 2 cores; GPU: {gpu}\n\ncode: abc123\n"
    )
    return p


def _table(tmp_path):
    """A figure's table: 3 cases; 'slow' is dearer and worse than localized(10) (dominated); traced exact."""
    d = tmp_path / "reports" / "figX"
    d.mkdir(parents=True)
    errs = {"classical": 0.8, "localized(iterations=10)": 0.05, "slow(k=1)": 0.08, "traced": 0.0,
            "unbenched(k=3)": 0.01, "truth_at_hit": 0.0}  # fmt: skip
    rows = []
    for c in range(3):
        for lab, e in errs.items():
            rows.append({"case": f"c{c}", "method": lab.split("(")[0], "label": lab, "family": lab.split("(")[0],
                         "cube_res": 64, "wrong_fraction": e * (1 + 0.1 * c)})  # fmt: skip
    _write(d / "metrics.csv", rows)
    return tmp_path / "reports"


TIMES = {"classical": 0.05, "localized(iterations=10)": 0.06, "slow(k=1)": 0.5}


def test_study_pareto_writes_the_page_and_plots(tmp_path):
    reports = _table(tmp_path)
    gpu = _bench(tmp_path, "gpu", "cuda", TIMES, exact_ms=0.2)
    cpu = _bench(tmp_path, "cpu", "llvm", {k: 100 * v for k, v in TIMES.items()}, exact_ms=30.0)
    out = tmp_path / "pareto"
    res = run_cli("pareto", "--reports", str(reports), "--out", str(out),
                                   "--benches", f"{gpu},{cpu}", "--clock", "wall")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert (out / "figX.png").read_bytes()[:4] == b"\x89PNG"
    md = (out / "pareto.md").read_text()
    scale = 1920 * 1080 / 1024**2
    d = pareto.device_times(gpu, clock="wall")
    assert d.device.startswith("NVIDIA Testcard") and d.code == "abc123" and d.backend == "cuda"
    assert d.ms["classical"] == pytest.approx(0.05 * scale) and d.ms["traced"] == pytest.approx(0.2 * scale)
    assert "NVIDIA Testcard" in md and "Test CPU, 2 cores" in md and "1.978" in md
    table = md.split("## figX")[1]
    line = {r.split("|")[1].strip(): r for r in table.splitlines() if r.startswith("| ")}
    assert "◆" in line["localized(iterations=10)"] and "◆" not in line["slow(k=1)"]  # dominated
    assert "◆" in line["traced"] and line["traced"].count("◆") == 2  # exact, at 0.396 ms / 59.3 ms
    assert "unbenched(k=3)" in table.split("Not benched")[1] and "truth_at_hit" not in table
    # GPU budgets 0.15, 0.3, 0.6, 1.5 ms: localized(10) at 0.119 ms, traced at 0.396 ms (0 wrong rays)
    gpu_line = next(r for r in table.splitlines() if r.startswith("- **gpu**"))
    assert (
        "0.15 ms → `localized(iterations=10)`" in gpu_line
        and "0.3 ms → `localized(iterations=10)`" in gpu_line
    )
    assert "0.6 ms → `traced`" in gpu_line and "1.5 ms → `traced`" in gpu_line
    cpu_line = next(r for r in table.splitlines() if r.startswith("- **cpu**"))
    assert "40 ms → `localized(iterations=10)`" in cpu_line and "80 ms → `traced`" in cpu_line
    assert "dearer on the front: `slow" not in md and "costs 0.396 ms here (the bare query" in md
    assert "no front method is dearer" in md


def test_the_synthetic_batch_and_bad_options(tmp_path):
    gpu = _bench(tmp_path, "gpu", "cuda", TIMES, exact_ms=0.2)
    d = pareto.device_times(gpu, batch="synthetic", clock="wall")
    assert d.ms["classical"] == pytest.approx(0.5 * 1920 * 1080 / 1024**2)
    k = pareto.device_times(gpu, clock="kernel")  # the kernels' device time: its own column, traced's too
    assert k.ms["classical"] == pytest.approx(0.025 * 1920 * 1080 / 1024**2)
    assert k.ms["traced"] == pytest.approx(0.05 * 1920 * 1080 / 1024**2)
    reports = _table(tmp_path)
    for args, words in (
        (["--batch", "nope"], "unknown batch 'nope'; allowed: close-up"),
        (["--metric", "nope"], "unknown metric 'nope'; allowed: wrong_fraction"),
        (["--clock", "nope"], "unknown clock 'nope'; allowed: wall, kernel"),
        (["--benches", str(tmp_path / "missing.csv")], "no such bench table"),
    ):
        res = run_cli(*["pareto", "--reports", str(reports), "--out", str(tmp_path / "o"), *args]
                                 + ([] if "--benches" in args else ["--benches", str(gpu)]))  # fmt: skip
        assert res.exit_code == 2 and words in res.output and res.output.count("\n") == 1, res.output


def test_the_report_shows_each_tables_front_where_study_pareto_wrote_it(tmp_path):
    """``study report`` puts reports/pareto/<table>.png under its table's section (and links pareto.md); without
    the plot, nothing."""
    import shutil

    from study.report import report, sections

    reports = tmp_path / "reports"
    (reports / "fig5").mkdir(parents=True)
    for f in ("metrics.csv", "metadata.json"):
        shutil.copy(f"reports/fig5/{f}", reports / "fig5" / f)
    assert sections.pareto_plot(reports, "fig5") == []
    assert not any(b[0] == "img" and "pareto" in b[1] for b in report.blocks(reports))
    (reports / "pareto").mkdir()
    (reports / "pareto" / "fig5.png").write_bytes(b"\x89PNG")
    (reports / "pareto" / "pareto.md").write_text("# front\n")
    imgs = [b[1] for b in report.blocks(reports) if b[0] == "img"]
    assert "pareto/fig5.png" in imgs


def test_the_commands_metric_help_names_every_error_column():
    """`study pareto --help` lists the error columns without importing the plots (the command imports them)."""
    import inspect

    from study.cli import commands

    help_text = inspect.signature(commands.pareto).parameters["metric"].default.help
    assert all(k in help_text for k in pareto.ERRORS)


def test_the_default_clock_is_the_kernels_and_traced_is_priced_with_its_shading(tmp_path):
    """Issue 56: the front's default clock is the kernels' (the launch share stated apart); a bench row of
    ``traced`` priced with its shading (path ``shaded``) gives its price, the bare query stated beside it; an older
    bench without one prices ``traced`` at the bare query and says so; ``hit_cache`` without its own row (its cache
    read unpriced) is not placed at the bare query's price."""
    reports = _table(tmp_path)
    gpu = _bench(tmp_path, "gpu", "cuda", TIMES, exact_ms=0.2)
    scale = 1920 * 1080 / 1024**2
    old = pareto.device_times(gpu)  # default: kernel clock
    assert old.clock == "kernel" and old.ms["classical"] == pytest.approx(0.025 * scale)
    assert old.wall["classical"] == pytest.approx(0.05 * scale)
    assert old.ms["traced"] == pytest.approx(0.05 * scale) and "traced" in old.unshaded
    assert "hit_cache(res=32)" not in old.ms  # no row of its own: its read is not priced, so not placed
    rows = list(csv.DictReader(open(gpu)))
    batch = rows[0]["batch"]
    shaded = {"batch": batch, "backend": "cuda", "path": "shaded", "label": "traced", "ms_per_frame": 0.9,
              "kernel_ms_per_frame": 0.6, "query_ms_per_frame": 0.2}  # fmt: skip
    _write(gpu, [{**r, "query_ms_per_frame": ""} for r in rows] + [shaded])
    d = pareto.device_times(gpu)
    assert d.ms["traced"] == pytest.approx(0.6 * scale) and d.bare["traced"] == pytest.approx(0.2 * scale)
    assert d.unshaded == [] and d.ms["traced_glossy(samples=4)"] == pytest.approx(4 * 0.6 * scale)
    out = tmp_path / "o"
    res = run_cli("pareto", "--reports", str(reports), "--out", str(out), "--benches", str(gpu))
    assert res.exit_code == 0, res.output
    md = (out / "pareto.md").read_text()
    assert "the device time in the kernels alone" in md and "Launch share left out" in md
    assert f"costs {0.6 * scale:.3g} ms here (the query and the shading of its hit; the bare query" in md
    assert f"the bare query {0.2 * scale:.3g} ms" in md
