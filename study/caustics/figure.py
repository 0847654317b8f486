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

from study.cache import Cache, content_key
from study.caustics import lightmap
from study.caustics import photons as caustics
from study.caustics.study import (
    CausticSetup,
    caustic_rows,
    direct_irradiance,
    load_caustic_config,
    radiance,
    sphere_radiance,
)
from study.codehash import code_hash
from study.errors import StudyError
from study.evaluate.metrics import to_ldr
from study.harness import budget
from study.harness.runner import metadata, run_cases
from study.harness.sweep import Case
from study.io import atomic_savefig, output_set
from study.tables import write_csv

_SETUPS: dict[tuple, tuple] = {}          # (config, backend, cache) → (cfg, scene, methods, setup), per process


def _setup(config: str, backend: str, cache: str | None):
    key = (str(config), backend, cache)
    if key not in _SETUPS:
        cfg, scene, methods = load_caustic_config(config)
        _SETUPS[key] = (cfg, scene, methods, CausticSetup(cfg, scene, backend=backend, cache=Cache(cache)))
    return _SETUPS[key]


def _resolution_case(config: str, backend: str, cache: str | None, res: int) -> list[dict]:
    """Worker: the sweep's rows at one caustic-map resolution (module-level, so worker processes can run it)."""
    cfg, scene, methods, S = _setup(config, backend, cache)
    return caustic_rows(cfg, scene, methods, resolutions=[res], setup=S)


def sweep_plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    labels = list(dict.fromkeys(r["label"] for r in rows if r["method"] != "exact"))
    for lab in labels:
        rs = [r for r in rows if r["label"] == lab]
        x = [r["caustic_res"] for r in rs]
        axes[0].loglog(x, [r["lm_rmse"] for r in rs], "o-", label=lab)
        axes[1].semilogx(x, [r["energy_ratio"] for r in rs], "o-", label=lab)
        axes[2].loglog(x, [r.get("img_rmse_mitsuba", np.nan) for r in rs], "o-", label=lab)
        axes[3].loglog(x, [r["seconds_per_map"] * 1e3 for r in rs], "o-", label=lab)
    ex = [r for r in rows if r["method"] == "exact"]
    if ex:
        axes[2].loglog([r["caustic_res"] for r in ex], [r["img_rmse_mitsuba"] for r in ex], "k--",
                       label="exact photons (a)")
        axes[2].axhline(ex[0]["mitsuba_noise_rmse"], color="gray", ls=":", label="Mitsuba noise")
    for ax, t in zip(axes, ["light-map RMSE vs exact photons (W/m²)", "caustic energy ratio vs exact",
                            "caustic image RMSE vs Mitsuba", "ms per caustic map (CPU)"]):
        ax.set_title(t, fontsize=9); ax.set_xlabel("caustic-map resolution")
    axes[0].legend(fontsize=7); axes[2].legend(fontsize=7)
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=100)


def fig8(config: str | Path, out: str | Path, *, backend: str = "numpy", cache: str | Path | None = ".cache",
         sweep: bool = False, progress=None) -> list[dict]:
    """Figure 8 (``<out>/fig8.png``, ``<out>/fig8.csv``) and, with ``sweep``, the sweep (``<out>/sweep.csv``,
    ``<out>/sweep.png``) over the config's resolutions × methods. Returns the rows written."""
    cfg, scene, methods = load_caustic_config(config)
    out = Path(out)
    budget.check_backend(backend)
    cache_s = str(cache) if cache else None
    show = next((m for m in methods if m.label == (cfg.show or methods[-1].label)), None)
    if show is None:
        raise StudyError(f"show names {cfg.show!r}, not among the methods", file=str(config), key="show")
    *_, S = _setup(str(config), backend, cache_s)
    owns = ["fig8.csv", "fig8.png"] + (["sweep.png", "sweep/results.csv", "sweep/metadata.json"] if sweep else [])
    with output_set(out, owns, keeps=["sweep/cases"] if sweep else ["sweep"]) as tmp:
        return _fig8_files(config, cfg, scene, methods, show, S, tmp, out, backend=backend, cache_s=cache_s,
                           sweep=sweep, progress=progress)


def _fig8_files(config, cfg, scene, methods, show, S, tmp: Path, out: Path, *, backend: str, cache_s: str | None,
                sweep: bool, progress) -> list[dict]:
    """Figure 8 and, with ``sweep``, the sweep, written into ``tmp`` (the case files under ``out/sweep/cases``)."""
    res = cfg.caustic.res
    rows = caustic_rows(cfg, scene, [show], resolutions=[res], setup=S)
    write_csv(rows, tmp / "fig8.csv")
    # ------------------------------------------------------------------ images
    cm = caustics.build_caustic_map(scene, show, S.env, S.uvmap, res=res)
    E = S.lightmaps(cm)
    Eref = S.lightmaps(caustics.exact_caustic_map(scene, S.tracer, res=res))
    Ed = direct_irradiance(scene, S.tracer, S.rec)
    Ec = lightmap.sample(E, S.rec.surface, S.rec.uv)
    ours_full = S.rec.image(radiance(S.albedo, S.rec, Ed + Ec) + sphere_radiance(scene, S.rec, show, S.env))
    sph = ~S.mask
    mi_full = np.where(sph[..., None], S.mi["path"], S.mi["full"])
    c_ours, c_ex, c_mi = S.caustic_image(E), S.caustic_image(Eref), S.mi["caustic"]
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 4, figsize=(15, 8))
    vmax = float(np.percentile(c_mi[S.mask].mean(-1), 99.9))
    def lum(a): return np.where(S.mask, a.mean(-1), np.nan)
    panels = [(ax[0, 0], to_ldr(ours_full), f"ours: direct + caustic map {res}², {show.label}"),
              (ax[0, 1], to_ldr(mi_full), "Mitsuba: ptracer (+ path on the sphere)"),
              (ax[1, 0], lum(c_ours), "caustic only: ours"),
              (ax[1, 1], lum(c_ex), "caustic only: exact photon tracing (a)"),
              (ax[1, 2], lum(c_mi), "caustic only: Mitsuba (glass − black sphere)")]
    for a, img, t in panels:
        a.imshow(img, cmap="inferno", vmin=0, vmax=vmax, interpolation="nearest") if img.ndim == 2 else a.imshow(img)
        a.set_title(t, fontsize=9)
    e1 = ax[0, 2].imshow(lum(c_ours - c_mi), cmap="coolwarm", vmin=-vmax / 2, vmax=vmax / 2)
    ax[0, 2].set_title("ours − Mitsuba (caustic only)", fontsize=9)
    ax[0, 3].imshow(lum(c_ours - c_ex), cmap="coolwarm", vmin=-vmax / 2, vmax=vmax / 2)
    ax[0, 3].set_title("ours − exact photons (caustic only)", fontsize=9)
    ax[1, 3].imshow(lum(S.mi["caustic_noise"]), cmap="coolwarm", vmin=-vmax / 2, vmax=vmax / 2)
    ax[1, 3].set_title("Mitsuba noise: (seed 1 − seed 2)/2", fontsize=9)
    fig.colorbar(e1, ax=ax[:, 3], fraction=0.03, label="radiance difference (W/m²/sr)")
    for a in ax.ravel():
        a.set_xticks([]); a.set_yticks([])
    r = rows[-1]
    fig.suptitle(f"fig8: glass sphere n={scene.object.material.ior}, caustic map {res}², {show.label}; "
                 f"image RMSE vs Mitsuba {r['img_rmse_mitsuba']:.3g} (Mitsuba noise {r['mitsuba_noise_rmse']:.3g}), "
                 f"light-map RMSE vs exact {r['lm_rmse']:.3g} W/m²", fontsize=10)
    atomic_savefig(fig, tmp / "fig8.png", dpi=100)
    if sweep:
        labels = [m.label for m in methods]
        code = code_hash(_resolution_case, *[type(m) for m in methods])
        content = (scene.model_dump(mode="json"), cfg.caustic.model_dump(mode="json"),
                   cfg.mitsuba.model_dump(mode="json"), labels, backend, code, "caustics")
        cases = [Case(i, f"r{res:04d}", scene, {"caustic.res": str(res)}, key=content_key(*content, res))
                 for i, res in enumerate(cfg.resolutions)]
        meta = metadata(config, backend=backend, seed=scene.render.seed, methods=labels,
                        cases=len(cases), kind="caustics", code_hash=code)

        def check(c: Case, rows: list[dict]) -> bool:
            """One row per method, as configured (+ exact photon tracing's, where Mitsuba renders are known),
            all at the case's resolution."""
            res, exact = int(c.labels["caustic.res"]), [r for r in rows if r.get("method") == "exact"]
            return ([r.get("label") for r in rows if r.get("method") != "exact"] == labels
                    and len(exact) == (S.mi is not None) and all(r.get("caustic_res") == res for r in rows))
        srows, _ = run_cases(cases, out / "sweep", meta, lambda c: (_resolution_case, (
            str(config), backend, cache_s, int(c.labels["caustic.res"]))),
            progress=(lambda done, n, cid: progress(done, n)) if progress else None, check=check,
            into=tmp / "sweep")
        sweep_plot(srows, tmp / "sweep.png")
        rows = rows + srows
    return rows
