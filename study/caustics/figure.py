"""Figure 8 (``<out>/fig8.png``, ``<out>/fig8.csv``) and the caustic-map sweep over resolutions × methods.

The sweep runs on the shared case runner (:func:`study.harness.runner.run_cases`): one case per caustic-map
resolution, resumed, locked and tabled like any sweep, under ``<out>/sweep/`` (``results.csv``, ``cases/``,
``metadata.json``), with its curves in ``<out>/sweep.png``. A case's key is its content: the scene, the caustic
and Mitsuba parameters, the methods, the resolution, the backend and the hash of the code that computes its rows.
Figure 8's files and the sweep's table, metadata and curves are one output set (:func:`study.io.output_set`),
swapped in together when all are written: a failed or killed run leaves the previous ones as they were.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from study import progress as pg
from study.cache import Cache, content_key
from study.caustics import display, lightmap
from study.caustics import photons as caustics
from study.caustics.study import (
    CausticSetup,
    caustic_rows,
    check_budget,
    direct_irradiance,
    load_caustic_config,
    radiance,
    sphere_radiance,
)
from study.codehash import code_hash
from study.errors import StudyError
from study.harness import budget
from study.harness.runner import metadata, run_cases
from study.harness.sweep import Case
from study.io import atomic_savefig, output_set
from study.tables import write_csv

_SETUPS: dict[tuple, tuple] = {}  # (config, backend, cache) → (cfg, scene, methods, setup), per process


def _setup(config: str, backend: str, cache: str | None):
    key = (str(config), backend, cache)
    if key not in _SETUPS:
        cfg, scene, methods = load_caustic_config(config)
        _SETUPS[key] = (
            cfg,
            scene,
            methods,
            CausticSetup(cfg, scene, backend=backend, cache=Cache(cache), methods=methods),
        )
    return _SETUPS[key]


def _resolution_case(config: str, backend: str, cache: str | None, res: int) -> list[dict]:
    """Worker: the sweep's rows at one caustic-map resolution (module-level, so worker processes can run it)."""
    cfg, scene, methods, S = _setup(config, backend, cache)
    return caustic_rows(cfg, scene, methods, resolutions=[res], setup=S)


def sweep_plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullLocator

    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    labels = list(dict.fromkeys(r["label"] for r in rows if r["method"] != "exact"))
    for lab in labels:
        rs = [r for r in rows if r["label"] == lab]
        x = [r["caustic_res"] for r in rs]
        axes[0].loglog(x, [r["lm_rmse"] for r in rs], "o-", label=lab)
        axes[1].semilogx(x, [r["energy_ratio"] for r in rs], "o-", label=lab)
        axes[2].loglog(x, [r.get("img_rmse_mitsuba", np.nan) for r in rs], "o-", label=lab)
        axes[3].loglog(x, [r["seconds_per_map"] * 1e3 for r in rs], "o-", label=lab)
    res = sorted({int(r["caustic_res"]) for r in rows})
    ex = [r for r in rows if r["method"] == "exact"]
    if ex:
        axes[2].loglog(
            [r["caustic_res"] for r in ex],
            [r["img_rmse_mitsuba"] for r in ex],
            "k--",
            label="exact photons (a)",
        )
        axes[2].axhline(ex[0]["mitsuba_noise_rmse"], color="gray", ls=":", label="Mitsuba noise")
    for ax, t in zip(
        axes,
        [
            "light-map RMSE vs exact photons (W/m²)",
            "caustic energy ratio vs exact",
            "caustic image RMSE vs Mitsuba",
            "ms per caustic map (CPU)",
        ],
    ):
        ax.set_title(t, fontsize=9)
        ax.set_xlabel("caustic-map resolution")
        # the resolutions measured, plainly (a log axis labels its minor ticks 2×10¹, 3×10¹, … over each other)
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xticks(res, [str(v) for v in res])
    # one legend for the four panels, below them (inside, it covered the lines it names)
    handles, names = axes[2].get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", ncol=len(names), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    atomic_savefig(fig, path, dpi=100)


def fig8(
    config: str | Path,
    out: str | Path,
    *,
    backend: str = "numpy",
    cache: str | Path | None = ".cache",
    sweep: bool = False,
    progress=None,
) -> list[dict]:
    """Figure 8 (``<out>/fig8.png``, ``<out>/fig8.csv``) and, with ``sweep``, the sweep (``<out>/sweep.csv``,
    ``<out>/sweep.png``) over the config's resolutions × methods. Returns the rows written. Progress: stages of
    the figure, then the sweep's cases (:mod:`study.progress`)."""
    with pg.task("fig8", None):
        return _fig8(config, out, backend, cache, sweep, progress)


def _fig8(config, out, backend, cache, sweep, progress) -> list[dict]:
    mark = pg.Stages()
    mark("load")
    cfg, scene, methods = load_caustic_config(config)
    out = Path(out)
    budget.check_backend(backend)
    check_budget(cfg, scene, sweep=sweep, source=str(config))
    cache_s = str(cache) if cache else None
    show = next((m for m in methods if m.label == (cfg.show or methods[-1].label)), None)
    if show is None:
        raise StudyError(f"show names {cfg.show!r}, not among the methods", file=str(config), key="show")
    mark("capture")  # the impostor, Mitsuba's renders, the light maps' frames
    *_, S = _setup(str(config), backend, cache_s)
    mark.end()
    owns = ["fig8.csv", "fig8.png"] + (
        ["sweep.png", "sweep/results.csv", "sweep/metadata.json"] if sweep else []
    )
    with output_set(out, owns, keeps=["sweep/cases"] if sweep else ["sweep"]) as tmp:
        return _fig8_files(
            config,
            cfg,
            scene,
            methods,
            show,
            S,
            tmp,
            out,
            backend=backend,
            cache_s=cache_s,
            sweep=sweep,
            progress=progress,
        )


def _fig8_files(
    config,
    cfg,
    scene,
    methods,
    show,
    S,
    tmp: Path,
    out: Path,
    *,
    backend: str,
    cache_s: str | None,
    sweep: bool,
    progress,
) -> list[dict]:
    """Figure 8 and, with ``sweep``, the sweep, written into ``tmp`` (the case files under ``out/sweep/cases``)."""
    res = cfg.caustic.res
    mark = pg.Stages()
    mark("methods")  # the caustic map of the method shown, measured, and Figure 8's images
    rows = caustic_rows(cfg, scene, [show], resolutions=[res], setup=S)
    write_csv(rows, tmp / "fig8.csv")
    # ------------------------------------------------------------------ images (display only: not in fig8.csv)
    cp, s1, s2 = cfg.caustic, *cfg.mitsuba.seeds[:2]
    cm, ex = (
        caustics.build_caustic_map(scene, show, S.env, S.uvmap, res=res),
        caustics.exact_caustic_map(scene, S.tracer, res=res),
    )
    E, Eex = (display.splat_adaptive(c, S.frames, res=cp.lightmap_res, sigma=cp.sigma) for c in (cm, ex))
    Ed = direct_irradiance(scene, S.tracer, S.rec)
    room = radiance(S.albedo, S.rec, Ed + lightmap.sample(E, S.rec.surface, S.rec.uv))
    indirect = display.mitsuba_indirect(scene, cfg.mitsuba.max_depth, Cache(cache_s))
    ours = S.rec.image(room + sphere_radiance(scene, S.rec, show, S.env)) + indirect
    glass = display.mitsuba_display(scene, cfg.mitsuba.max_depth, Cache(cache_s))["glass"]
    mi_full = np.where(~S.mask[..., None], glass, S.mi["full"])
    c_ours, c_mi = S.caustic_image(E), S.mi["caustic"]
    r = rows[-1]
    adaptive = float(np.sqrt(np.mean((c_ours - c_mi)[S.mask] ** 2)))
    display.draw(
        tmp / "fig8.png",
        ours=ours,
        mitsuba=mi_full,
        mitsuba_noise=(S.mi[f"pt_glass_{s1}"] - S.mi[f"pt_glass_{s2}"]) / 2,
        mask=S.mask,
        caustics={
            f"caustic only: ours (kNN splats, k={display.K_NEIGHBOURS})": c_ours,
            "caustic only: exact photon tracing (a), kNN splats": S.caustic_image(Eex),
            "caustic only: Mitsuba (glass − black sphere)": c_mi,
        },
        measured=S.caustic_image(S.lightmaps(cm)) - S.caustic_image(S.lightmaps(ex)),
        title=f"fig8: glass sphere n={scene.object.material.ior}, caustic map {res}², {show.label}. "
        f"Ours = point light with shadow rays + indirect light baked from Mitsuba (caustic-free) + caustic "
        f"light map.\nLight-map RMSE vs exact photons {r['lm_rmse']:.3g} W/m² (σ = {cp.sigma * 1e3:g} mm); "
        f"caustic image RMSE vs Mitsuba {r['img_rmse_mitsuba']:.3g} (σ = {cp.sigma * 1e3:g} mm), "
        f"{adaptive:.3g} (kNN splats); Mitsuba noise {r['mitsuba_noise_rmse']:.3g}",
    )
    mark.end()
    if sweep:
        labels = [m.label for m in methods]
        code = code_hash(_resolution_case, *[type(m) for m in methods])
        content = (
            scene.model_dump(mode="json"),
            cfg.caustic.model_dump(mode="json"),
            cfg.mitsuba.model_dump(mode="json"),
            labels,
            backend,
            code,
            "caustics",
        )
        cases = [
            Case(i, f"r{res:04d}", scene, {"caustic.res": str(res)}, key=content_key(*content, res))
            for i, res in enumerate(cfg.resolutions)
        ]
        meta = metadata(
            config,
            backend=backend,
            seed=scene.render.seed,
            methods=labels,
            cases=len(cases),
            kind="caustics",
            code=(_resolution_case, *[type(m) for m in methods]),
        )

        def check(c: Case, rows: list[dict]) -> bool:
            """One row per method, as configured (+ exact photon tracing's, where Mitsuba renders are known),
            all at the case's resolution."""
            res, exact = int(c.labels["caustic.res"]), [r for r in rows if r.get("method") == "exact"]
            return (
                [r.get("label") for r in rows if r.get("method") != "exact"] == labels
                and len(exact) == (S.mi is not None)
                and all(r.get("caustic_res") == res for r in rows)
            )

        srows, _ = run_cases(
            cases,
            out / "sweep",
            meta,
            lambda c: (_resolution_case, (str(config), backend, cache_s, int(c.labels["caustic.res"]))),
            progress=(lambda done, n, cid: progress(done, n)) if progress else None,
            check=check,
            into=tmp / "sweep",
            name="caustics sweep",
        )
        sweep_plot(srows, tmp / "sweep.png")
        rows = rows + srows
    return rows
