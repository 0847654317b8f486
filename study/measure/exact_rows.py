"""Where the exact row is not the exact image, the run says so for that row.

The exact rows are the methods that trace the rays (``traced``, ``traced_glossy``: their class names its own
``bench_query``). On a mirror, ``traced`` shows the truth's image (:func:`study.measure.inputs.exact_shading`) and
ranks first or ties on every column that measures the method (tests/scene/test_exact_ranks.py). Elsewhere it is an
estimate with errors of its own, and a stand-in can beat it on such a column:

* a glass object whose far side comes from its own distance map (``render.exit = "distance_map"``, the default for
  meshes): ``traced`` traces the methods' rays through that map, not the exactly refracted ones, and path traces
  their radiance with a seed of its own, so its error against the truth is the exit's and that noise;
* a rough object: ``traced_glossy(samples=K)`` averages K lobe rays a pixel, each path traced with a seed of its
  own, against the truth's lobe average: its error is mostly that sampling noise (falling as 1/√K).

No ranking places the exact rows among the stand-ins (:func:`study.report.summary.ranking` ranks stand-ins only);
:func:`exact_notes` names, for each exact row that a stand-in beats on a column that measures the method
(:func:`measures_the_method`), the columns, the closest case and the cause, in one line that ``study run`` prints
and the run's page carries (:func:`study.measure.lighting.notes`).
"""

from __future__ import annotations

import math

from study import columns
from study import methods as registry

#: Columns of the picture, not of a method (study.measure.worth, study.measure.exposure): the same on every row.
PICTURE = ("firefly_fraction", "black_share", "clipped_share", "mirrored_void")
#: Units of what a row costs, not how close it comes.
COST_UNITS = ("lookups", "s")
#: Columns a note names before the others (study run's own, then these), and how many it names at most.
LEAD_COLUMNS = ("rmse_truth", "relmse_truth_exposed", "wrong_fraction", "flip_truth")
NAMED = 4


def measures_the_method(col: str) -> bool:
    """A declared column with a direction that measures how close the method comes to the exact hits or the truth:
    not an interval's end (``_lo``/``_hi``), not against the oracle's map (``*_oracle``, ``dec_*``: the map's own
    error on an exact row) nor Mitsuba's render (``*_mitsuba``: light no method models), not a cost, not the
    picture's."""
    d = columns.declared(col)
    if (
        col.endswith(("_lo", "_hi"))
        or d is None
        or d.lower_is_better is None
        or d.unit in COST_UNITS
        or col in PICTURE
    ):
        return False
    return "oracle" not in col and "mitsuba" not in col and not col.startswith("dec_")


def is_exact(row: dict) -> bool:
    """Whether the row is an exact row: its method's class declares its own ``bench_query`` (the exact query)."""
    cls = registry.REGISTRY.get(str(row.get("method", "")))
    return cls is not None and "bench_query" in vars(cls)


def _number(v) -> float:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan


def outranked(rows: list[dict]) -> dict[str, list[tuple[str, float, str, float]]]:
    """Exact row label → [(column, its value, the best stand-in's label, that one's value)] on every column that
    measures the method (:func:`measures_the_method`) where a stand-in is better beyond rounding (1e-6 relative),
    study run's columns first."""
    from study.tables import REFERENCE_ROWS

    exact = [r for r in rows if is_exact(r)]
    stand = [r for r in rows if not is_exact(r) and r.get("label") not in REFERENCE_ROWS]
    out: dict[str, list[tuple[str, float, str, float]]] = {}
    for e in exact:
        for col in e:
            if not measures_the_method(col):
                continue
            v = _number(e.get(col))
            if math.isnan(v):
                continue
            low = columns.declared(col).lower_is_better
            tie = 1e-6 + 1e-6 * abs(v) if math.isfinite(v) else 0.0
            vals = [(_number(r.get(col)), r["label"]) for r in stand]
            better = [(x, lab) for x, lab in vals if (x < v - tie if low else x > v + tie)]
            if better:
                x, lab = (min if low else max)(better)
                out.setdefault(e["label"], []).append((col, v, lab, x))
    first = [*columns.view("run"), *LEAD_COLUMNS]
    for beaten in out.values():  # study run's columns first, then the headline's, then the table's order
        beaten.sort(key=lambda b: first.index(b[0]) if b[0] in first else len(first))
    return out


def cause(row: dict) -> str:
    """Why the exact row is not the exact image here, with the key that changes it."""
    if _number(row.get("object_alpha")) > 0:
        k = row.get("knob_value")
        k = f"{_number(k):g}" if math.isfinite(_number(k)) else "K"
        return (
            f"on this rough object its error is its own sampling noise: {k} lobe rays a pixel, each path traced "
            "with a seed of its own, against the truth's lobe average (more samples bring it down as 1/√K)"
        )
    if row.get("exit") == "distance_map":
        return (
            "on this glass object it traces the methods' rays through the object's distance map "
            '(render.exit = "distance_map"), not the exactly refracted ones, and path traces their radiance with a '
            'seed of its own (render.exit = "exact" traces the exact rays: the truth\'s image)'
        )
    return "it path traces the radiance along rays that are not the truth's with a seed of its own"


def exact_notes(rows: list[dict]) -> list[str]:
    """One line per exact row that a stand-in beats on a column that measures the method ('' nowhere)."""
    by = {r["label"]: r for r in rows if is_exact(r)}
    lines = []
    for lab, beaten in outranked(rows).items():
        col, v, other, x = beaten[0]
        rest = [c for c, *_ in beaten[1:NAMED]]
        more = f" and {len(beaten) - NAMED} more" if len(beaten) > NAMED else ""
        also = f"; also {', '.join(rest)}{more}" if rest else ""
        lines.append(
            f"{lab} is not the exact image here and ranks below a stand-in on {len(beaten)} "
            f"{'columns that measure' if len(beaten) > 1 else 'column that measures'} the method ({col} {v:.3g} "
            f"against {other}'s "
            f"{x:.3g}{also}): {cause(by[lab])}; no ranking places it among the stand-ins"
        )
    return lines
