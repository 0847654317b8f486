"""The rows of study's other tables — the bench's, its measured floors and RT-core projection, the caustics', the
report's power table — declared as the results table is (:mod:`study.column_rows`), each with the views its
printed tables show (:func:`study.columns.table_columns`).
"""

from __future__ import annotations

from study.column_rows import HIGH, LOW, C, F

_MS = "ms per 1024² frame"
_X = "× (> 1: the method is faster)"

#: table → (its rows in the order its CSV writes them, view → its columns in order)
TABLES = {
    # study bench (study/bench/output.py): one row per batch × backend × path × method
    "bench": (
        [
            C("batch", note="the bench's batch of rays (position, scene)"),
            C("backend", note="numpy, llvm or cuda (or the exact tracer's)"),
            C("path", note="the kernel path or the exact query timed"),
            C("label", note="the method with its parameters, or 'exact: …'"),
            C("rays", unit="count"),
            C("lookups_mean", unit="lookups", lower_is_better=LOW),
            C(
                "bytes_per_ray",
                unit="B",
                lower_is_better=LOW,
                note="the fetches' bytes (4 texels × 4 B a channel)",
            ),
            C("ms_per_call", unit="ms", lower_is_better=LOW),
            C("mrays_per_s", unit="Mrays/s", lower_is_better=HIGH),
            C("ms_per_frame", unit=_MS, lower_is_better=LOW),
            C("kernel_ms_per_frame", unit=_MS, lower_is_better=LOW, note="the kernel alone (device timers)"),
            C("query_ms_per_frame", unit=_MS, lower_is_better=LOW),
            C("floor_ms_per_frame", unit=_MS, note="what its lookups cost at the measured fetch rate"),
            C("x_floor", unit="×", note="ms_per_frame over the floor"),
            C("kernel_x_floor", unit="×"),
            C("x_vs_embree", unit=_X, lower_is_better=HIGH),
            C("x_vs_mitsuba", unit=_X, lower_is_better=HIGH),
            C("x_vs_preliminary", unit=_X, lower_is_better=HIGH),
            C("x_vs_ray_test", unit=_X, lower_is_better=HIGH),
            C("kernel_x_vs_preliminary", unit=_X, lower_is_better=HIGH),
        ],
        {
            "headline": [
                "batch",
                "backend",
                "label",
                "lookups_mean",
                "bytes_per_ray",
                "ms_per_frame",
                "kernel_ms_per_frame",
                "floor_ms_per_frame",
                "x_floor",
                "kernel_x_floor",
                "x_vs_preliminary",
                "x_vs_ray_test",
                "x_vs_mitsuba",
                "kernel_x_vs_preliminary",
            ],
        },  # fmt: skip
    ),
    "bench_floors": (
        [C("backend"), C("cube_res", unit="texels"), C("quantity"), C("value"), C("unit")],
        {},
    ),
    # the projection to GPUs with RT cores (study/bench/carry.py)
    "projection": (
        [
            C("batch"),
            C("label"),
            C("lookups_mean", unit="lookups"),
            C("bytes_per_ray", unit="B"),
            C("ms_per_frame", unit=_MS),
            C("gpu", note="the GPU projected to"),
            C("ms_per_frame_projected", unit=_MS),
            C("exact_ms_projected", unit=_MS, note="the exact trace with RT cores on"),
            C("x_vs_preliminary_low", unit=_X),
            C("x_vs_preliminary_high", unit=_X),
            C("traced_shaded_ms_projected", unit=_MS),
        ],
        {},
    ),
    # Figure 8 and the caustic-map sweep (study/caustics/study.py): one row per map resolution × method
    "caustics": (
        [
            C("caustic_res", unit="texels", views=("report", "printed")),
            C("label", views=("report", "printed")),
            C("photons", unit="count", views=("report",)),
            C(
                "lm_rmse",
                unit="W/m²",
                lower_is_better=LOW,
                views=("report", "printed"),
                note="light map against exact photon tracing",
            ),
            C("lm_relmse", lower_is_better=LOW, views=("report", "printed")),
            C("energy_ratio", note="the light map's energy over the exact photons'", views=("printed",)),
            C(
                "img_rmse_mitsuba",
                unit="linear RGB",
                lower_is_better=LOW,
                views=("report", "printed"),
                note="the image against Mitsuba's ptracer",
            ),
            C("img_sum_ratio_mitsuba", views=("report",)),
            C("mitsuba_noise_rmse", unit="linear RGB", views=("report", "printed")),
            C("photon_angle_p95_deg", unit="deg", lower_is_better=LOW, views=("report",)),
            C("seconds_per_map", unit="s", lower_is_better=LOW, views=("report", "printed")),
        ],
        {},
    ),  # fmt: skip
    # the report's power table (study/report/power.py): one row per results table
    "power": (
        [
            C("table"),
            C("cases", unit="count", note="distinct geometries"),
            C("seeds", unit="count", note="seeds per geometry"),
            C("rays_min", unit="count"),
            C("rays_median", unit="count"),
            C("hidden_min", unit="count"),
            C("hidden_max", unit="count"),
            C("hidden_cases", unit="count", note="cases with enough hidden rays for a claim about them"),
            C("best_wrong", unit=F, note="the best method's median wrong fraction"),
            C("mdd_rays", unit=F, note="the smallest rise one case detects over its fewest rays"),
            C("mdd_hidden", unit=F),
            C("mdd_cases_sd", note="over the cases, in sd of the per-case differences"),
            C("mdd_cases", unit=F),
        ],
        {},
    ),
}
