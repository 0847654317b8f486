"""Cost that carries to other GPUs: what each method reads per ray, and a *projection* (not a measurement) of the
bench's GPU rows to GPUs with RT cores.

Per ray (every method row of the main table)
    ``lookups_mean``: the distance lookups the rays of the batch spent on average (``Trace.lookups``);
    ``lookups_bound``: the method's ``lookup_bound`` at the bench's cube resolution (what the floor counts);
    ``bytes_per_ray``: the texel bytes the rays touch at most, ``(lookups_mean + 1) · 16`` (a bilinear fetch of the
    1-channel float32 distance texture reads 4 texels of 4 B; + 1: the origin check of ``Method.trace``) ``+ 64``
    (the colour at the shown point: 4 texels of a 4-channel float32 texture) ``+`` :data:`~study.bench.floors.
    BYTES_PER_RAY` (the ray read, the outputs written). Texture caches make the real traffic smaller; the count
    carries from one GPU to another, a time does not.

Projection (:func:`projection_rows`, from the headline rows measured on a GPU without RT cores)
    A method at its fetch floor (``x_floor`` ≈ 1) is bound by the texture rate, so its time is scaled by the
    ratio of bilinear texture rates (:data:`TEXTURE_RATE`, from unit counts and clocks); the exact query
    (``ray_intersect_preliminary``) measured with OptiX traversing in software is divided by the speed-up RT cores
    gave OptiX (:data:`RT_CORE_FACTOR`: ×4.3, ×3.5–5 by scene, RTX 2080 Ti, NVIDIA developer forum) and scaled by
    nothing else. Both are assumptions, written in the table's title; the projected ratio is a range.
    ``traced_shaded_ms_projected``: tracing *and shading* the ray as ``traced`` is priced (``study.bench.run.
    exact_query_row``), with the RT-core factor applied to its traversals only (the hit query and the shadow ray)
    and the rest (the SurfaceInteraction, the material) kept as measured (:func:`shaded_parts`).
"""

from __future__ import annotations

from study import columns
from study.bench.floors import BYTES_PER_RAY

#: Bilinear texture rates, GTexel/s (8-bit, from texture-unit counts and boost clocks; /work field notes).
TEXTURE_RATE = {"H100/H200": 1045.0, "RTX 4090": 1290.0, "L40S": 1431.0}
#: GPUs with RT cores that the projection targets.
RT_GPUS = ("RTX 4090", "L40S")
#: OptiX with RT cores on over off: (low, typical, high).
RT_CORE_FACTOR = (3.5, 4.3, 5.0)
#: Bytes a bilinear fetch reads: 4 texels × 4 B per channel (1-channel distance, 4-channel colour).
FETCH_BYTES = {1: 16, 4: 64}

PROJECTION_COLS = columns.table_columns("projection")  # study/column_tables.py


def shaded_parts(rows: list[dict], variant: str = "cuda_ad_rgb") -> dict[str, tuple[float, float]]:
    """Batch → (traversal ms, other ms) per 1024² frame of tracing and shading a ray on ``variant``'s rows of the
    bench table: the traversals are ``ray_intersect_preliminary`` and the ``shadow_ray``, the rest the full
    ``ray_intersect``'s SurfaceInteraction over the preliminary query and the ``shade_material``; batches without
    those rows are left out."""
    by: dict[str, dict[str, float]] = {}
    for r in rows:
        if r.get("label") == f"exact: Mitsuba {variant}" and _num(r.get("ms_per_frame")) is not None:
            by.setdefault(r["batch"], {})[r.get("path", "")] = _num(r["ms_per_frame"])
    out = {}
    for b, t in by.items():
        need = ("ray_intersect", "ray_intersect_preliminary", "shade_material", "shadow_ray")
        if all(k in t for k in need):
            si = max(t["ray_intersect"] - t["ray_intersect_preliminary"], 0.0)
            out[b] = (t["ray_intersect_preliminary"] + t["shadow_ray"], si + t["shade_material"])
    return out


def cost_columns(lookups_mean: float, lookups_bound: float) -> dict:
    """``lookups_mean``, ``lookups_bound`` and ``bytes_per_ray`` of one method row (module docstring)."""
    return {
        "lookups_mean": lookups_mean,
        "lookups_bound": lookups_bound,
        "bytes_per_ray": (lookups_mean + 1) * FETCH_BYTES[1] + FETCH_BYTES[4] + BYTES_PER_RAY,
    }


def _num(v) -> float | None:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if f == f else None


def projection_rows(
    rows: list[dict], measured_on: str = "H100/H200", shading: dict | None = None
) -> list[dict]:
    """Projected ms per 1024² frame and ratio to the exact query on each of :data:`RT_GPUS`, from the ``cuda``
    frozen rows of ``rows`` measured on ``measured_on`` (a GPU without RT cores); [] without such rows. With
    ``shading`` (:func:`shaded_parts`), also tracing and shading the ray with the RT-core factor on its traversals
    only (``traced_shaded_ms_projected``)."""
    shading = shading or {}
    out = []
    for r in rows:
        ms, x = _num(r.get("ms_per_frame")), _num(r.get("x_vs_preliminary"))
        if r.get("backend") != "cuda" or r.get("path") != "frozen" or ms is None or x is None:
            continue
        exact = ms * x  # the exact query's ms per frame, measured (software traversal)
        for gpu in RT_GPUS:
            scale = TEXTURE_RATE[measured_on] / TEXTURE_RATE[gpu]
            proj, lo, hi = ms * scale, exact / RT_CORE_FACTOR[2], exact / RT_CORE_FACTOR[0]
            out.append(
                {
                    "batch": r["batch"],
                    "label": r["label"],
                    "lookups_mean": r.get("lookups_mean", ""),
                    "bytes_per_ray": r.get("bytes_per_ray", ""),
                    "ms_per_frame": ms,
                    "gpu": gpu,
                    "ms_per_frame_projected": proj,
                    "exact_ms_projected": exact / RT_CORE_FACTOR[1],
                    "x_vs_preliminary_low": lo / proj,
                    "x_vs_preliminary_high": hi / proj,
                    "traced_shaded_ms_projected": (
                        shading[r["batch"]][0] / RT_CORE_FACTOR[1] + shading[r["batch"]][1]
                        if r["batch"] in shading
                        else ""
                    ),
                }
            )
    return out


def projection_title(measured_on: str = "H100/H200") -> str:
    lo, mid, hi = RT_CORE_FACTOR
    return (
        f"PROJECTION, not a measurement: methods scaled by bilinear texture rate ({measured_on} "
        f"{TEXTURE_RATE[measured_on]:g} GTexel/s → "
        + ", ".join(f"{g} {TEXTURE_RATE[g]:g}" for g in RT_GPUS)
        + f"); the exact query (ray_intersect_preliminary, measured with software traversal) divided by the RT-core "
        f"speed-up of OptiX, ×{mid:g} (×{lo:g}–{hi:g}: x_vs_preliminary_low/high); traced_shaded_ms_projected: "
        f"tracing and shading the ray, the speed-up applied to its traversals only (the hit and the shadow ray)"
    )
