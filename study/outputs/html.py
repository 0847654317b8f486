"""``reports/index.html``: the report's blocks (:func:`study.outputs.report.blocks`) as one page that works offline.

The page is self-contained apart from files under ``reports/`` it names by relative paths (figure PNGs, plots, each
figure's viewer scripts ``<fig>/viewer/<case>.js`` and EXRs): no CDN, no server, opened as ``file://``. Its script and
style (``viewer.js``, ``html.css`` beside this module) are inlined: tables sort by a click on a header (numbers by
value, empty cells last), and each case of a figure gets an image viewer (sources by number keys, ←/→ or clicks;
layers — image, angular error, outcome, FLIP, hidden — by ↑/↓ or clicks; zoom by the wheel or buttons, pixelated;
drag to pan; an exposure slider for the linear radiance; the value under the cursor). Each viewer reads its images
from its script when it scrolls into view. What a figure lacks (no viewer images, EXRs not made here) is said in
the page, never an error.
"""

from __future__ import annotations

import html as _html
import json
import math
import re
from pathlib import Path

from study.outputs import viewer
from study.tables import fmt_number

_HERE = Path(__file__).resolve().parent


def esc(s) -> str:
    return _html.escape(str(s), quote=True)


def inline(md: str) -> str:
    """The inline Markdown the report writes (`code`, **strong**, *emphasis*, [text](link)) as HTML."""
    out = []
    for i, part in enumerate(str(md).split("`")):
        if i % 2:
            out.append(f"<code>{esc(part)}</code>")
            continue
        t = esc(part)
        t = re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", lambda m: f'<a href="{m.group(2)}">{m.group(1)}</a>', t)
        t = re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", t)
        t = re.sub(r"(?<![\w*])\*([^*\s][^*]*?)\*(?![\w*])", r"<em>\1</em>", t)
        out.append(t)
    return "".join(out)


def _sort_value(v) -> str | None:
    """A cell's value for sorting (``data-v``): numbers as JavaScript reads them, NaN as empty; None for text."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    if isinstance(v, float) and math.isnan(v):
        return ""
    return repr(float(v)) if math.isfinite(v) else ("Infinity" if v > 0 else "-Infinity")


def table(rows: list[dict], cols: list[str]) -> str:
    """A sortable HTML table of ``rows`` with the columns ``cols`` that some row has (numbers as in Markdown)."""
    cols = [c for c in cols if any(c in r for r in rows)]
    head = "".join(f'<th title="sort by {esc(c)}">{esc(c)}</th>' for c in cols)
    body = []
    for r in rows:
        cells = []
        for c in cols:
            v = r.get(c, "")
            sv = _sort_value(v)
            cells.append(
                f'<td data-v="{sv}" class="num">{esc(fmt_number(v, 3))}</td>'
                if sv is not None
                else f"<td>{inline(v)}</td>"
            )
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (
        f'<div class="scroll"><table class="sortable"><thead><tr>{head}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table></div>"
    )


# ---------------------------------------------------------------------------------------------- viewers
def _figure_viewers(reports: Path, fig: str) -> dict | None:
    """A figure's viewer manifest with what exists here marked: ``missing`` per case (its script), ``have`` per
    layer (its EXR); None where the figure has no viewer images."""
    m = viewer.read_manifest(reports / fig)
    if m is None:
        return None
    for c in m["cases"]:
        c["script"] = f"{fig}/{c['script']}"
        c["missing"] = not (reports / c["script"]).is_file()
        c["exr"] = f"{fig}/{c.get('exr', '')}"
        for la in c["layers"]:
            la["exr"] = f"{fig}/{la.get('exr', '')}"
            la["have"] = (reports / la["exr"]).is_file()
    return m


def viewer_note(reports: Path, fig: str) -> str:
    """One Markdown line on a figure's per-case images (for ``index.md``)."""
    m = _figure_viewers(reports, fig)
    if m is None:
        return (
            f"No per-case images for {fig} here: `study figure {fig}` writes them (EXRs under `{fig}/exr/`, the "
            f"viewer's images under `{fig}/viewer/`)."
        )
    have = sum(la["have"] for c in m["cases"] for la in c["layers"])
    exr = (
        f"EXRs per case under [{fig}/exr/]({fig}/exr/)"
        if have
        else f"EXRs per case (`{fig}/exr/<case>.exr`) are not in this copy: `bash scripts/reproduce.sh` makes them"
    )
    return f"Per-case image viewer ({len(m['cases'])} cases): [index.html](index.html#viewers-{fig}); {exr}."


def _viewers_html(reports: Path, fig: str, manifests: dict) -> str:
    m = _figure_viewers(reports, fig)
    if m is None:
        return (
            f'<p class="note" id="viewers-{esc(fig)}">No per-case images for {esc(fig)} in this copy: '
            f"<code>study figure {esc(fig)}</code> writes them (viewer images and EXRs).</p>"
        )
    manifests[fig] = m
    have = sum(la["have"] for c in m["cases"] for la in c["layers"])
    note = (
        ""
        if have
        else f" EXR files are not in this copy (<code>bash scripts/reproduce.sh</code> makes them "
        f"under <code>{esc(fig)}/exr/</code>)."
    )
    divs = "".join(
        f'<div class="viewer" tabindex="0" data-fig="{esc(fig)}" data-case="{i}"></div>'
        for i in range(len(m["cases"]))
    )
    return (
        f'<h3 id="viewers-{esc(fig)}">{esc(fig)}: images per case</h3><p class="note">Click a viewer, then: '
        "number keys or ←/→ pick the image, ↑/↓ the layer (image, angular error, outcome, …), wheel or +/− to "
        "zoom (f: fit), drag to pan; the slider sets the exposure of the linear radiance (0 = as rendered, "
        f'clipped at 1, sRGB).{note}</p><div class="viewers">{divs}</div>'
    )


def _luts() -> dict:
    """The colour maps the viewers use, 256 RGB entries each (matplotlib's)."""
    import matplotlib

    names = {d["cmap"] for d in viewer.DISPLAY.values() if "cmap" in d}
    return {
        n: [[round(255 * x) for x in matplotlib.colormaps[n](i / 255)[:3]] for i in range(256)] for n in names
    }


def _script_json(obj) -> str:
    """JSON to embed in a <script type="application/json">: no '</' that would end the element."""
    return json.dumps(obj, allow_nan=False).replace("</", "<\\/")


# ---------------------------------------------------------------------------------------------- the page
def page(blocks: list[tuple], reports: Path, *, title: str) -> str:
    """The blocks as one HTML page (``index.html``)."""
    body, toc, manifests = [], [], {}
    for b in blocks:
        kind = b[0]
        if kind == "h":
            anchor = re.sub(r"[^a-z0-9]+", "-", b[2].lower()).strip("-")
            if b[1] == 2:
                toc.append(f'<a href="#{anchor}">{inline(b[2])}</a>')
            body.append(f'<h{b[1]} id="{anchor}">{inline(b[2])}</h{b[1]}>')
        elif kind == "p":
            body.append(f"<p>{inline(b[1])}</p>")
        elif kind == "list":
            body.append("<ul>" + "".join(f"<li>{inline(t)}</li>" for t in b[1]) + "</ul>")
        elif kind == "table":
            body.append(table(b[1], b[2]))
        elif kind == "img":
            body.append(
                f'<figure><a href="{esc(b[1])}"><img src="{esc(b[1])}" alt="{esc(b[2])}"></a></figure>'
            )
        elif kind == "media":
            tag = (
                f'<video src="{esc(b[1])}" controls loop muted></video>'
                if b[1].endswith((".mp4", ".webm"))
                else f'<img src="{esc(b[1])}" alt="{esc(b[2])}">'
            )
            body.append(
                f'<figure>{tag}<figcaption><a href="{esc(b[1])}">{esc(b[1])}</a></figcaption></figure>'
            )
        elif kind == "viewer":
            body.append(_viewers_html(reports, b[1], manifests))
    css = (_HERE / "html.css").read_text(encoding="utf-8")
    js = (_HERE / "viewer.js").read_text(encoding="utf-8")
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f"<title>{esc(title)}</title>",
            f"<style>{css}</style></head><body>",
            f'<nav class="toc">{" · ".join(toc)}</nav><main>',
            *body,
            "</main>",
            f'<script type="application/json" id="study-manifest">{_script_json(manifests)}</script>',
            f'<script type="application/json" id="study-luts">{_script_json(_luts() if manifests else {})}</script>',
            f"<script>{js}</script>",
            "</body></html>",
            "",
        ]
    )
