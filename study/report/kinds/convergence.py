"""The ``convergence`` kind (``configs/convergence.toml``, ``study convergence`` or ``study figure convergence``):
each search's wrong fractions against its iterations or steps (:mod:`study.outputs.convergence`); in the report,
beside the paper's figures, the curves and the rung each scene needs to reach the targets, with its interval."""

from __future__ import annotations

from pathlib import Path

from study.outputs.convergence import run_convergence
from study.outputs.markup import link
from study.report.kinds import FigureKind, register_kind
from study.tables import read_csv


def convergence_figure(config, out, *, backend: str = "numpy", cache=".cache", **_) -> list[dict]:
    """``run_convergence`` as a figure kind (the camera quality is the figures' own: ``quality`` is not used)."""
    return run_convergence(config, out, backend=backend, cache=cache)


def convergence_section(reports: Path, d: Path, table: list[dict], cols: list[str]) -> list[tuple]:
    """The curves (convergence.png) and reach.csv: per scene, ladder and error column, the rung after which the
    median case stays within each target, with the interval over the cases."""
    reach = read_csv(d / "reach.csv")
    rel = d.relative_to(reports).as_posix()
    out = [
        ("h", 2, "Convergence: each search against its iterations"),
        (
            "p",
            "The paper says the search converges very quickly in convex rooms of large planes (Fig. 4) and still "
            "pretty fast where tops of columns hide (Fig. 5), without a number; these curves are the number: "
            "localized's wrong fractions against its false-position iterations and the marches' against their "
            "steps, per case of the figures named in the config, and the rung each scene needs to reach the "
            f"targets ({link(f'{rel}/reach.csv', f'{rel}/reach.csv')}; cases, causes of the remaining wrong rays: "
            f"{link(f'{rel}/index.md', f'{rel}/index.md')}; study/outputs/convergence.py).",
        ),
    ]
    if (d / "convergence.png").is_file():
        out.append(("img", f"{rel}/convergence.png", "convergence"))
    return out + ([("table", reach, list(reach[0]))] if reach else [])


def convergence_lines(rows: list[dict]) -> list[str]:
    return [f"{len({r['case'] for r in rows})} cases, {len(rows)} rungs"]


CONVERGENCE = register_kind(
    FigureKind(
        name="convergence",
        run=convergence_figure,
        files=("curves.csv", "reach.csv"),
        section=convergence_section,
        lines=convergence_lines,
    )
)
