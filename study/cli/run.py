"""``study run``: one scene, the methods named, measured and written, without a config file.

    study run scenes/room.toml --method classical --method "localized(iterations=3)" \\
        --set render.cube_res=64 --set 'camera.eye=[0, 1.5, -1.9]' --out reports/run-room

SCENE is a scene TOML, a mesh file (the environment: OBJ/PLY/GLB/STL/OFF) or a Mitsuba XML file
(:func:`study.api.load_scene`). ``--set KEY=VALUE`` overrides a dotted scene key; VALUE is a TOML value (a bare
word is taken as a string: ``--set object.shape=torus``). The table is printed and written with the images to
``--out`` by :meth:`study.api.Result.save`: the table, one multi-layer EXR, the image grid PNG and a viewer page
(``index.html``), as a figure's; ``study report`` shows it as a section. The default ``--out`` is
``reports/run-<scene stem>-<8 hex digits of its resolved path>``, one folder per scene file: two files named
``room.*`` never replace each other's results, and a re-run of the same file replaces its own.
"""

from __future__ import annotations

import re
import time
import tomllib
from pathlib import Path

import typer

from study import columns, progress
from study.cli.app import app, console, guarded
from study.cli.commands import folder
from study.errors import StudyError
from study.io import file_stem


def parse_sets(items: list[str]) -> dict:
    """``["object.radius=0.3", "camera.eye=[0,1,2]"]`` → ``{"object.radius": 0.3, "camera.eye": [0, 1, 2]}``;
    a malformed item is one StudyError naming ``--set`` and the item."""
    out = {}
    for item in items:
        key, eq, text = item.partition("=")
        key, text = key.strip(), text.strip()
        if not eq or not re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*", key):
            raise StudyError(
                f"expected KEY=VALUE with a dotted scene key (e.g. object.radius=0.3), got {item!r}",
                key="--set",
            )
        try:
            out[key] = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            if not re.fullmatch(r"[A-Za-z_][\w.+-]*", text):
                raise StudyError(
                    f"the value of {key} is not a TOML value ({text!r}); numbers as 0.3, lists as "
                    '[0, 1, 2], strings as "text"',
                    key="--set",
                ) from None
            out[key] = text  # a bare word: a string
    return out


@app.command()
@guarded(llvm=True)
def run(
    scene: Path = typer.Argument(..., help="scene TOML, mesh file (environment) or Mitsuba XML"),
    method: list[str] = typer.Option(
        [],
        "--method",
        "-m",
        metavar="NAME",
        help="method name or label, e.g. classical or 'localized(iterations=3)' (repeatable; default: all)",
    ),
    set_: list[str] = typer.Option(
        [], "--set", "-s", metavar="KEY=VALUE", help="override a scene key, VALUE as TOML (repeatable)"
    ),
    backend: str = typer.Option("numpy", help="numpy | llvm | cuda: where the methods run"),
    out: str | None = typer.Option(
        None,
        metavar="PATH",
        help="output directory (default reports/run-<scene stem>-<hash of its path>: one per scene file)",
    ),
    cache: Path = typer.Option(Path(".cache"), help="cache directory for impostors and renders"),
    allow_mismatch: bool = typer.Option(
        False, help="score methods that do not model the object's surface (rows marked surface_mismatch)"
    ),
):
    """Evaluate methods on one scene, no config file: prints the table, writes table + images to --out."""
    from rich.console import Console
    from rich.table import Table

    from study.api import evaluate, load_scene, method_list
    from study.outputs.run_files import default_folder

    t0 = time.perf_counter()  # the time reported includes loading and placing the scene
    out = folder(out)  # --out "": one line, before any work
    overrides = parse_sets(set_)
    methods = method_list(method, key="--method") if method else "all"  # all: the family fitting the surface
    with progress.task(f"run {scene.name}", 1):  # stages on stderr (study.cli.progress)
        with progress.stage("load"):
            sc = load_scene(scene, overrides)
        t_load = time.perf_counter() - t0
        if sc.load_summary():  # what the environment's file held, and what was ignored (stderr)
            typer.echo(sc.load_summary(), err=True)
        if sc.placement_line():  # automatic placement's choice, its score terms named (stderr)
            typer.echo(sc.placement_line(), err=True)
        out = out or default_folder(scene)  # reports/run-<stem>-<hash of the path>: one per scene file
        with progress.item(file_stem(scene.stem)):
            res = evaluate(
                sc, methods, backend=backend, cache=cache, source=str(scene), allow_mismatch=allow_mismatch
            )
        progress.advance(file_stem(scene.stem))
        for line in res.notes():  # weak lights, fireflies, a noisy truth (study.measure.lighting)
            typer.echo(f"note: {line}", err=True)
        shown = res.shown()
        t = Table(title=res.summary())
        headers = columns.headers()  # the declared short headers (the files keep the names)
        for c in shown.columns:
            t.add_column(headers.get(c, c), justify="left" if c == "label" else "right", overflow="fold")
        for row in shown.itertuples(index=False):
            t.add_row(*(f"{v:.3g}" if isinstance(v, float) else str(v) for v in row))
        wide = Console(width=max(console.width, 150), highlight=False, markup=False)  # no cell cut to "…"
        wide.print(t)
        with progress.stage("outputs"):
            res.save(out)
        console.print(
            f"run: wrote {out} in {time.perf_counter() - t0:.1f} s (loading and placement {t_load:.1f} s)",
            highlight=False,
        )
        console.print(f"run: time split: {progress.split_line(res.times)}", highlight=False)
