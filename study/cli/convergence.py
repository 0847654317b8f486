"""``study convergence``: each search's wrong fractions, angles and image error against its iterations or steps,
per case; the rungs it needs to reach 5 % / 1 % per scene; which rays it gets wrong
(:mod:`study.outputs.convergence`)."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from study.cli.app import app, console, guarded
from study.cli.commands import folder
from study.cli.run import parse_sets
from study.harness.config import shipped
from study.outputs.convergence import run_convergence


@app.command()
@guarded(llvm=True)
def convergence(
    config: Path = typer.Argument(Path("configs/convergence.toml"), help="convergence config (TOML)"),
    out: str = typer.Option("reports/convergence", metavar="PATH", help="output directory"),
    backend: str = typer.Option("numpy", help="numpy | llvm | cuda: where the methods run"),
    cache: Path = typer.Option(Path(".cache"), help="cache directory for impostors and renders"),
    set_: list[str] = typer.Option(
        [], "--set", "-s", metavar="KEY=VALUE", help="override a scene key in every case (repeatable)"
    ),
):
    """Convergence curves: curves.csv, reach.csv, breakdown.csv, convergence.png and index.md under <out>."""
    out = folder(out)
    t0 = time.perf_counter()
    rows = run_convergence(shipped(config), out, backend=backend, cache=cache, overrides=parse_sets(set_))
    n = len({r["case"] for r in rows})
    console.print(
        f"convergence: wrote {out} ({n} cases) in {time.perf_counter() - t0:.1f} s", highlight=False
    )
