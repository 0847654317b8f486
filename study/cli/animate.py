"""``study animate``: curved objects (Figure 4's sphere, a torus) moving along a path, methods side by side with their
errors (GIF, MP4), judged on the object's pixels over seed replicates."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from study.cli.app import app, console, guarded
from study.cli.commands import folder


@app.command()
@guarded(llvm=True)
def animate(
    config: Path = typer.Option(Path("configs/motion.toml"), help="motion config (TOML)"),
    out: str = typer.Option("reports/animation", metavar="PATH", help="output directory"),
    backend: str = typer.Option("numpy", help="numpy | llvm | cuda: where the methods run"),
    cache: Path = typer.Option(Path(".cache"), help="cache directory for impostors and renders"),
):
    """Render the motion config's frames (one case each, per sequence and seed) and write motion.gif /
    motion.mp4, frames.csv, motion.csv, motion.png and metadata.json under <out>."""
    from study.outputs.animation import animate as make_animation  # loaded by the command that needs it

    out = folder(out)
    t0 = time.perf_counter()
    rows = make_animation(config, out, backend=backend, cache=cache)  # progress: study.cli.progress
    frames = len({(r.get("sequence"), r.get("seed"), r["frame"]) for r in rows})
    console.print(
        f"animate: wrote {out} ({frames} frames: sequences × seeds × positions) in {time.perf_counter() - t0:.1f} s",
        highlight=False,
    )
