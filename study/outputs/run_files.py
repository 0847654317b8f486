"""What ``study run`` and :meth:`study.api.Result.save` write for one scene, like a figure's outputs: the image grid
PNG, one multi-layer EXR, the viewer's images, and a page that shows them (``index.html``, offline, the report's
viewer), with the run's notes on its light and samples (:func:`study.measure.lighting.notes`: on the page, in
``index.json``; a picture that is mostly fireflies says so in its titles). Made in memory (relative path →
bytes) for :func:`study.io.write_set`."""

from __future__ import annotations

import hashlib
from pathlib import Path

from study.io import file_stem
from study.measure import lighting
from study.outputs import figures, html, viewer

#: The one case of a run: its file names (exr/run.exr, viewer/run.js, run.png).
CASE = "run"
#: A run's images are exposed as a person would set them for the whole picture (not for the object's highlights):
#: :func:`study.measure.exposure.auto_exposure` of Mitsuba's render, stated in the PNG's title and index.json.
RUN_EXPOSURE_RULE = f"Mitsuba image: {viewer.FRAME_RULE}"


def default_folder(scene: str | Path, reports: Path = Path("reports")) -> Path:
    """Where ``study run SCENE`` writes without ``--out``: ``reports/run-<stem>-<8 hex>``, the hex digits of the
    SHA-256 of the file's resolved path — two files of one name (``a/room.glb``, ``b/room.obj``) never share a
    folder, and a re-run of the same file replaces its own."""
    from study.harness.config import shipped

    path = shipped(Path(scene).expanduser()).resolve()
    digest = hashlib.sha256(str(path).encode("utf-8", "surrogateescape")).hexdigest()[:8]
    return reports / f"run-{file_stem(Path(scene).stem)}-{digest}"


def run_exposure(res) -> float:
    """The exposure (EV) of a run's images: :data:`RUN_EXPOSURE_RULE` (0 where Mitsuba's render shows no light)."""
    ev = viewer.auto_exposure(getattr(res, "mitsuba", None))
    return 0.0 if ev is None else ev


def result_files(
    res, rows: list[dict], labels: list[str], *, title: str, name: str | None = None
) -> tuple[dict[str, bytes | str], dict]:
    """``res``: a case's images and maps (attributes as :class:`~study.measure.case.CaseOutput`); ``rows``: its
    table; ``labels``: the methods; ``name``: the scene file's (titles its viewer). Returns the files and the
    viewer manifest entry's layer names (``{"exr": …, "layers": {group: {label: layer}}}``) for ``index.json``."""
    exposure = run_exposure(res)
    said = lighting.notes(rows, res.scene)  # weak lights, fireflies, a noisy truth: stated with the images
    title = f"{title} — {label}" if (label := lighting.picture_label(rows)) else title
    files: dict[str, bytes | str] = dict(
        figures.image_grids(
            CASE,
            [res],
            labels,
            title=title,
            occlusion_panel=getattr(res, "occluded", None) is not None,
            outcome_panel=bool(res.outcome_maps),
            row_labels=[CASE],
            exposure=exposure,
            rule=RUN_EXPOSURE_RULE,
            wrap=True,  # one case: rows of legible panels, however many methods
        )
    )
    more, entry = viewer.case_files(CASE, CASE, res, labels, title=title, case_id=CASE, exposure_ev=exposure)
    files.update(more)
    manifest = {"figure": CASE, "cases": [entry]}
    files[viewer.MANIFEST] = viewer.manifest_text(CASE, [entry])
    blocks = [
        ("h", 1, f"study run: {title}"),
        (
            "p",
            f"The image grid ([{CASE}.png]({CASE}.png)), one multi-layer EXR ([{entry['exr']}]({entry['exr']})) "
            "and the table ([table.csv](table.csv)) of one scene; `study report` shows it beside the figures.",
        ),
        *[("img", p, p) for p in files if p.endswith(".png")],
        ("p", html.SHADOW_NOTE),
        *[("p", f"**Note:** {line}.") for line in said],
        ("viewer", ".", f"{name or 'the scene'}: images per case"),
        ("table", rows, list(dict.fromkeys(k for r in rows for k in r))),
    ]
    files["index.html"] = html.page(blocks, Path("."), title=f"study run: {title}", made={".": manifest})
    index = {
        "exr": entry["exr"],
        "layers": {},
        "exposure_ev": round(exposure, 4),
        "exposure_rule": RUN_EXPOSURE_RULE,
        "notes": said,  # study.measure.lighting.notes
    }
    for la in entry["layers"]:
        index["layers"].setdefault(la["layer"], {})[la["source"]] = la["exr_layer"]
    return files, index
