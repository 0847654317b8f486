"""The commands that make results: ``figure``, ``sweep``, ``check``, ``report``, ``pareto``, ``bench``,
``caustics-sweep``, ``methods``. Argument parsing only: every command calls one function of the package."""

from __future__ import annotations

import json
import time
from pathlib import Path

import typer

from study import methods, progress
from study.cli.app import app, console, err_console, figures, guarded
from study.errors import StudyError
from study.harness.config import load_figure_config, plain_name, shipped
from study.io import file_stem, locked, out_dir
from study.outputs.case_images import image_choice


def folder(value: str | None, key: str = "--out") -> Path | None:
    """An output (or reports) folder option as a Path, None where it is not given; ``--out ""`` is one line, exit
    2 (:func:`study.io.out_dir`), never the current directory."""
    return None if value is None else out_dir(value, key=key)


# What each command runs (measurement, outputs, the bench) is imported by that command, so that ``study --help``
# and a command's bad input do not wait for it.


@app.command()
@guarded(llvm=True)
def figure(
    name: str | None = typer.Argument(
        None, help="figure to make: one of configs/fig*.toml (" + ", ".join(figures()) + ")"
    ),
    config: Path | None = typer.Option(
        None, help="figure config (default configs/<name>.toml); without NAME the outputs are named after it"
    ),
    out: str | None = typer.Option(None, metavar="PATH", help="output directory (default reports/<name>)"),
    backend: str = typer.Option("numpy", help="numpy | llvm | cuda: where the methods run"),
    cache: Path = typer.Option(Path(".cache"), help="cache directory for impostors and renders"),
    quality: str = typer.Option(
        "preview",
        help="preview: the config as written | paper: 1024² renders (reports/paper/<name>; a GPU job)",
    ),
    images: str = typer.Option("all", help="per-case images: all (EXRs and viewer) | viewer | none"),
):
    """Reproduce one of the paper's figures, or your own (--config ANY.toml): image grid, metrics, per-case EXRs
    and viewer images under reports/<name>/ (reports/paper/<name>/ with --quality paper)."""
    from study.harness.config import quality_overrides

    quality_overrides(quality)  # an unknown preset (or --images): one line, before any work
    image_choice(images)
    known = figures()
    if name is None and config is None:
        raise StudyError(f"name a figure or give --config; figures: {', '.join(known)}", key="name")
    if config is None and name not in known:
        raise StudyError(f"unknown figure {name!r}; allowed: {', '.join(known)}", key="name")
    config = Path(known[name]) if config is None else shipped(config)
    name = plain_name(name) if name else file_stem(config.stem)  # one folder under reports/, never a path
    out = folder(out) or (
        Path("reports") / name if quality == "preview" else Path("reports") / quality / name
    )
    t0 = time.perf_counter()
    from study.report.kinds import config_kind

    kind = config_kind(config)  # the config's `kind` (grid by default): study/report/kinds/
    rows = kind.make(config, out, name=name, backend=backend, cache=cache, quality=quality, images=images)
    lines = kind.printed(rows)  # a plug-in kind's failures: one line naming it (study.report.kinds)
    if lines is None:
        _print_table(rows)
    for line in lines or ():
        console.print(line, highlight=False)
    console.print(f"{name}: wrote {out} in {time.perf_counter() - t0:.1f} s", highlight=False)
    split = _time_split(out / "metadata.json")
    if split:  # where the time went (the grid kinds' metadata.json: "time_split", summed over the cases)
        console.print(f"{name}: time split: {progress.split_line(split)}", highlight=False)


def _time_split(meta: Path) -> dict:
    """The ``time_split`` a figure's ``metadata.json`` holds ({} where it holds none, or is not there)."""
    try:
        split = json.loads(meta.read_text()).get("time_split")
    except (OSError, ValueError, AttributeError):
        return {}
    return split if isinstance(split, dict) else {}


def _print_table(rows: list[dict]) -> None:
    from rich.table import Table

    t = Table(show_lines=False)
    from study import columns

    cols = [c for c in columns.view("figure") if any(c in r for r in rows)]
    for c in cols:
        t.add_column(c, justify="right" if c not in ("case", "label") else "left", overflow="fold")
    for r in rows:
        t.add_row(*(f"{r.get(c):.4g}" if isinstance(r.get(c), float) else str(r.get(c, "")) for c in cols))
    console.print(t)


@app.command()
@guarded(llvm=True)
def sweep(
    config: Path = typer.Argument(..., help="sweep file (TOML), e.g. configs/sweep.toml"),
    out: str | None = typer.Option(
        None, metavar="PATH", help="output directory (default reports/sweep-<config name>)"
    ),
    backend: str = typer.Option("numpy", help="numpy | llvm | cuda: where the methods run"),
    cache: Path = typer.Option(Path(".cache"), help="cache directory for impostors and renders"),
    jobs: int = typer.Option(1, min=1, max=64, help="cases run in parallel processes"),
    dask: str | None = typer.Option(
        None,
        help="run cases on a Dask cluster: scheduler address, "
        "'local' for a local cluster of --jobs workers, or "
        "'local-gpus' for --jobs workers per visible GPU",
    ),
    plots: bool = typer.Option(True, help="write the error curves next to the table"),
    images: str = typer.Option(
        "none", help="per-case images of the cases computed: none | viewer | all (+ EXRs)"
    ),
):
    """Run (or resume) a sweep: one row per case × method in <out>/results.csv, curves beside it."""
    from study.harness.cluster import check_address
    from study.harness.runner import prepare_sweep, run_sweep
    from study.outputs import case_images
    from study.outputs.plots import sweep_plots

    dask = check_address(dask)  # before any work: '' and 'banana' are refused, not run locally
    image_choice(images)
    out = folder(out) or Path("reports") / f"sweep-{config.stem}"  # a stem: one folder under reports/
    ready = prepare_sweep(config, backend=backend, jobs=jobs)  # every case checked before any work
    rows, stats = run_sweep(  # progress by case on stderr (study.cli.progress)
        config,
        out,
        backend=backend,
        cache=cache,
        jobs=jobs,
        dask=dask,
        prepared=ready,
        extra=(lambda rows, d: sweep_plots(rows, d / "plots")) if plots else None,  # in the output set
        images=None
        if images == "none"
        else (case_images.write_case, str(out), images, jobs == 1 and not dask),
    )
    if images != "none":  # the background writer's last files, then the viewer's manifest
        case_images.finish(out, out.name)
    console.print(
        f"sweep: {stats['cases']} cases ({stats['cached']} already done, {stats['computed']} computed) "
        f"in {stats['seconds']:.1f} s → {out / 'results.csv'}",
        highlight=False,
    )
    if "dask" in stats:  # the fixed cost apart from the steady throughput (also in metadata.json)
        from study.harness.cluster import timing_line

        console.print(timing_line(stats["dask"]), highlight=False)


@app.command()
@guarded(llvm=True)
def check(
    config: Path = typer.Option(Path("configs/check.toml"), help="check file: sweep, baseline, tolerances"),
    update: bool = typer.Option(
        False,
        "--update",
        "--update-baseline",
        help="rewrite the baseline: the sweep at each of the check file's seeds, mean and sd per metric",
    ),
    seed: int | None = typer.Option(
        None, help="run the check at this seed instead of the sweep's own", min=0
    ),
    backend: str = typer.Option("numpy", help="numpy | llvm | cuda"),
    cache: Path = typer.Option(Path(".cache"), help="cache directory for impostors and renders"),
):
    """CI regression: run a small fixed sweep and compare every metric with the committed baseline (its mean over
    seeds, within k × its seed-to-seed sd + a floor)."""
    from study.report.check import run_check

    fails, lines = run_check(  # progress: stderr
        shipped(config), update=update, cache=cache, backend=backend, seed=seed
    )
    for line in lines:
        console.print(line, highlight=False)
    if fails:
        for f in fails:
            err_console.print(f"regression: {f.message}", highlight=False, soft_wrap=True, markup=False)
        err_console.print(f"check failed: {len(fails)} problem(s)", highlight=False)
        raise typer.Exit(1)
    if not update:
        console.print("check passed", highlight=False)


@app.command()
@guarded()
def report(
    reports: str = typer.Option(
        "reports",
        metavar="PATH",
        help="directory holding the figures, sweeps and `study run` folders (found by their own files, any name)",
    ),
):
    """Build reports/index.md and reports/index.html (tables, image viewers) from the results tables: figures,
    tables, the paper's claims, versions."""
    from study.report.report import build_report

    reports = folder(reports, "--reports")
    path = build_report(reports)
    if path is None:  # one line on stderr, and no page of empty tables
        err_console.print(
            f"warning: found no results under {reports} (a figure's metrics.csv, a sweep's results.csv, a study "
            "run folder's index.json + table.csv + scene.json); nothing written",
            highlight=False,
            markup=False,
            soft_wrap=True,
        )
        return
    console.print(f"report: wrote {path} and {path.with_suffix('.html')}", highlight=False)


@app.command()
@guarded()
def verify(
    fresh: Path = typer.Argument(
        ..., help="folder of freshly made tables (a figure's or sweep's folder, or one above)"
    ),
    against: Path = typer.Option(Path("reports"), help="the committed reports to compare with"),
    out: Path | None = typer.Option(
        None, help="where to write the agreement table (Markdown); default: not written"
    ),
    note: str = typer.Option(
        "", help="a line under the title: how the fresh tables were made (command, host)"
    ),
):
    """Compare freshly made tables with the committed ones, row by row: values within their committed intervals
    (<col>_lo/_hi), deterministic columns within float tolerance on the same backend. Prints the agreement table;
    exit 1 where a value lies outside its interval."""
    from study.io import atomic_write
    from study.report.verify import agreement_markdown, compare_tables

    results = compare_tables(fresh, against)  # the page the same for the same tables: no timing in it
    text = agreement_markdown(results, fresh=fresh.as_posix(), committed=against.as_posix(), note=note)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(out, text)
    console.print(text, highlight=False, markup=False, soft_wrap=True)
    if any(r.outside for r in results) or any(r.det_differ for r in results if r.det_judged):
        raise typer.Exit(1)


@app.command()
@guarded()
def pareto(
    reports: str = typer.Option(
        "reports", metavar="PATH", help="directory holding the figures' and sweeps' tables"
    ),
    out: str = typer.Option(
        "reports/pareto", metavar="PATH", help="output directory: <table>.png per table, pareto.md"
    ),
    benches: str = typer.Option(
        "reports/performance/bench-gpu.csv,reports/performance/bench-cpu.csv",
        "--benches",
        help="comma list of bench tables (study bench's bench-<tag>.csv), one panel each",
    ),
    metric: str = typer.Option(
        "wrong_fraction", help="error column: wrong_fraction, rmse_truth_debiased or wrong_fraction_1cm"
    ),
    batch: str = typer.Option(
        "close-up", help="bench batch the times come from: close-up, fig4, synthetic, sorted"
    ),
    clock: str = typer.Option(
        "kernel",
        help="kernel: the device's time in the kernels (what a frame pays) | wall: ms per call, host share included",
    ),
):
    """The equal-cost front per figure and sweep: error (median over cases, with its interval) against measured ms
    per 1080p frame on each benched device, the Pareto front, and the method to use at a few budgets."""
    from study.report.pareto import write_pareto

    reports, out = folder(reports, "--reports"), folder(out)
    paths = [Path(b.strip()) for b in benches.split(",") if b.strip()]
    written = write_pareto(reports, out, paths, metric=metric, batch=batch, clock=clock)
    console.print(f"pareto: wrote {len(written) - 1} plots and {out / 'pareto.md'}", highlight=False)


@app.command()
@guarded(llvm=True)
def bench(
    out: str = typer.Option("reports/bench", metavar="PATH", help="output directory"),
    config: Path = typer.Option(Path("configs/fig4.toml"), help="figure config whose scene is benched"),
    position: int = typer.Option(2, help="index into the config's positions: where the object stands"),
    scene_res: int = typer.Option(1024, help="camera resolution (res²) of the fig4 ray batch"),
    rays: int = typer.Option(1024 * 1024, help="rays in the synthetic batch"),
    method_names: str = typer.Option(
        "all", "--methods", help="comma list of method names (all: every registered method)"
    ),
    ladder: bool = typer.Option(
        True, help="time each method at every value of its knob's ladder (--no-ladder: at its defaults only)"
    ),
    cube_res: int = typer.Option(256, help="impostor cube resolution"),
    backends: str = typer.Option("auto", help="comma list of numpy, llvm, cuda (auto: all available)"),
    repeats: int = typer.Option(5, help="timed repeats (median reported)"),
    numpy_max_rays: int = typer.Option(1 << 16, help="numpy is timed on at most this many rays"),
    scaling: bool = typer.Option(True, help="also run the scaling studies (plots)"),
    tag: str = typer.Option("", help="name of this machine in file names (default cpu or gpu)"),
):
    """Time every method against exact ray casting (Embree, Mitsuba) on the same rays: CSV + Markdown tables."""
    from study.bench.output import bench_table, write_bench_files, write_scaling
    from study.bench.run import BenchOptions, check_options, run_bench

    out = folder(out)
    cfg, scene, _ = load_figure_config(config)
    if cfg.positions is None or not 0 <= position < len(cfg.positions):
        n = len(cfg.positions or [])
        raise StudyError(
            f"position {position} out of range; allowed: 0..{n - 1}"
            if n
            else "the config lists no positions",
            file=str(config),
            key="positions",
        )
    chosen = () if method_names == "all" else tuple(m.strip() for m in method_names.split(",") if m.strip())
    names = () if backends == "auto" else tuple(b.strip() for b in backends.split(",") if b.strip())
    opt = BenchOptions(
        position=tuple(cfg.positions[position]),
        scene_res=scene_res,
        synthetic=rays,
        methods=chosen,
        ladder=ladder,
        cube_res=cube_res,
        backends=names,
        repeats=repeats,
        numpy_max_rays=numpy_max_rays,
        scaling=scaling,
        tag=tag,
    )
    check_options(opt)
    t0 = time.perf_counter()
    files: list[Path] = []
    with locked(out):  # the main table and the scaling study: each replaced whole, or left as it was
        rows, scal, info = run_bench(
            scene,
            opt,
            log=lambda s: err_console.print(f"[{time.perf_counter() - t0:7.1f} s] {s}", highlight=False),
            on_table=lambda rows, info: files.extend(write_bench_files(rows, info, out, lock=False)),
        )
        if scal:
            files += write_scaling(scal, info, out, lock=False)
    console.print(bench_table(rows), highlight=False, soft_wrap=True)
    console.print("wrote " + ", ".join(str(f) for f in files), highlight=False, soft_wrap=True)


def _caustics(config, out, backend, cache, *, sweep: bool):
    from study.report.kinds.caustics import caustics_figure, caustics_lines

    t0 = time.perf_counter()
    rows = caustics_figure(config, out, backend=backend, cache=cache, sweep=sweep)
    for line in caustics_lines(rows):
        console.print(line, highlight=False)
    console.print(f"wrote {out} in {time.perf_counter() - t0:.1f} s", highlight=False)


@app.command("caustics-sweep")
@guarded(llvm=True)
def caustics_sweep(
    config: Path = typer.Option(Path("configs/caustics_sweep.toml"), help="sweep config"),
    out: str = typer.Option("reports/fig8", metavar="PATH", help="output directory"),
    backend: str = typer.Option("numpy", help="numpy | llvm | cuda: where caustic maps are built"),
    cache: Path = typer.Option(Path(".cache"), help="cache directory"),
):
    """Figure 8 plus the caustic-map sweep (resolution × iterations × method): CSV + PNG under reports/fig8/."""
    _caustics(shipped(config), folder(out), backend, cache, sweep=True)


@app.command("methods")
@guarded()
def list_methods():
    """List the registered localization methods, their parameters (with what each one means) and knobs."""
    for name in methods.names():
        cls = methods.REGISTRY[name]
        fields = cls.Params.model_fields
        params = ", ".join(f"{k}={f.default!r}" for k, f in fields.items())
        knob = (
            f"  knob: {cls.knob.param} ∈ {{{', '.join(map(str, cls.knob.ladder))}}}"
            if cls.knob
            else "  knob: none"
        )
        lines = [f"  {k}: {f.description}" for k, f in fields.items() if f.description]
        console.print("\n".join([f"{name}({params})", *lines, knob]), highlight=False, soft_wrap=True)
