"""``study cache info`` and ``study cache clear``: what the cache of impostors and renders holds."""

from __future__ import annotations

from pathlib import Path

import typer

from study.cache import Cache
from study.cli.app import app, console, guarded

cache_app = typer.Typer(
    no_args_is_help=True, help="The cache of impostors and renders: what it holds, clearing it."
)
app.add_typer(cache_app, name="cache")


def _size(n: int) -> str:
    return next(
        f"{n / f:.1f} {u}"
        for f, u in ((1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB"), (1, "B"))
        if n >= f or u == "B"
    )


@cache_app.command("info")
@guarded()
def cache_info(cache: Path = typer.Option(Path(".cache"), help="cache directory")):
    """Entries and bytes per kind (radiance, distance, mitsuba, …)."""
    kinds = Cache(cache).info()
    for k, (n, size) in kinds.items():
        console.print(f"{k}: {n} entries, {_size(size)}", highlight=False, soft_wrap=True)
    total = sum(n for n, _ in kinds.values()), sum(s for _, s in kinds.values())
    console.print(f"cache {cache}: {total[0]} entries, {_size(total[1])}", highlight=False, soft_wrap=True)


@cache_app.command("clear")
@guarded()
def cache_clear(
    cache: Path = typer.Option(Path(".cache"), help="cache directory"),
    kind: str | None = typer.Option(None, help="remove only the entries of this kind"),
):
    """Remove the cache's entries (all, or those of one --kind); anything else in the directory stays."""
    gone = Cache(cache).clear(kind)
    for k, (n, size) in gone.items():
        console.print(f"{k}: removed {n} entries, {_size(size)}", highlight=False, soft_wrap=True)
    console.print(
        f"cache {cache}: removed {sum(n for n, _ in gone.values())} entries", highlight=False, soft_wrap=True
    )
