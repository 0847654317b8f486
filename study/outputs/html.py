"""``reports/index.html``: the report's blocks (:func:`study.report.report.blocks`) as one page that works offline.

The page is self-contained apart from files under ``reports/`` it names by relative paths (figure PNGs, plots, each
figure's viewer scripts ``<fig>/viewer/<case>.js`` and EXRs): no CDN, no server, opened as ``file://``. Its script and
style (``viewer.js``, ``html.css`` beside this module) are inlined. The page fits a 1280–1920 px window: the top bar
wraps its links, a table wider than the page scrolls in its own box, viewers share each row's width (one alone
takes the row, its controls beside the image). Tables sort by a click on a header (numbers by
value, empty cells last) and their headers stick under the top bar, and each case of a figure gets an image viewer
(sources by number keys, the references first, digits typed quickly forming one number, or ←/→ and clicks; layers —
image, angular error, outcome, FLIP, hidden — by ↑/↓ or clicks; r flips to truth_at_hit and back, d shows the
difference from it; zoom by the wheel or buttons, pixelated; drag to pan; an exposure slider for the linear
radiance; exposure and zoom shared by the viewers of a figure; the value under the cursor). Each viewer reads its
images from its script when it scrolls into view. What a figure lacks (no viewer images, EXRs not made here) is
said in the page, never an error. Names are text (:mod:`study.outputs.markup`).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from urllib.parse import quote

from study.outputs import viewer
from study.outputs.markup import Md, code, esc, inline, link
from study.tables import fmt_number

_HERE = Path(__file__).resolve().parent
#: tables longer than this (a figure's every case × method) are folded into a <details> the reader opens
OPEN_ROWS = 40


#: Why the methods' images show no shadow of the object while Mitsuba's does (study/measure/case.py, truth.py).
SHADOW_NOTE = (
    "Why the methods' images show no shadow of the object and *mitsuba* does: a method replaces only the object's "
    "own pixels, shaded by its secondary rays looked up in the impostor; everything around the object is "
    "Mitsuba's render of the scene *without* the object, and the impostor is captured without it too. So neither "
    "the methods nor *truth_at_hit* hold the object's shadow or interreflection; *mitsuba* is rendered with it."
)


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
    breaks = lambda c: re.sub(r"([_(,=])", r"\1<wbr>", esc(c))  # noqa: E731  (long headers: method labels)
    head = "".join(f'<th title="sort by {esc(c)}">{breaks(c)}</th>' for c in cols)
    body = []
    for r in rows:
        cells = []
        for c in cols:
            v = r.get(c, "")
            sv = _sort_value(v)
            wrap = ' class="wrap"' if len(str(v)) > 40 else ""  # long text wraps, the rest stays on one line
            cells.append(
                f'<td data-v="{sv}" class="num">{esc(fmt_number(v, 3))}</td>'
                if sv is not None
                else f"<td{wrap}>{inline(v) if isinstance(v, Md) else esc(v)}</td>"
            )
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (
        f'<div class="tablebox"><table class="sortable"><thead><tr>{head}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table></div>"
    )


# ---------------------------------------------------------------------------------------------- viewers
def _figure_viewers(reports: Path, fig: str, made: dict | None = None) -> dict | None:
    """A figure's viewer manifest with what exists here marked: ``missing`` per case (its script), ``have`` per
    layer (its EXR); None where the figure has no viewer images. ``fig`` ``"."``: the page is in the figure's own
    directory. ``made``: the manifest of files written together with the page (all there)."""
    m = viewer.read_manifest(reports / fig) if made is None else json.loads(json.dumps(made))
    if m is None:
        return None
    pre = "" if fig in ("", ".") else f"{fig}/"
    for c in m["cases"]:
        c["script"] = f"{pre}{c['script']}"
        c["missing"] = made is None and not (reports / c["script"]).is_file()
        c["exr"] = f"{pre}{c.get('exr', '')}"
        for la in c["layers"]:
            la["exr"] = f"{pre}{la.get('exr', '')}"
            la["have"] = made is not None or (reports / la["exr"]).is_file()
    return m


def viewer_note(reports: Path, fig: str) -> str:
    """One Markdown line on a figure's per-case images (for ``index.md``)."""
    m = _figure_viewers(reports, fig)
    if m is None:
        return (
            f"No per-case images for {code(fig)} here: {code(f'study figure {fig}')} writes them (EXRs under "
            f"{code(f'{fig}/exr/')}, the viewer's images under {code(f'{fig}/viewer/')})."
        )
    have = sum(la["have"] for c in m["cases"] for la in c["layers"])
    exr = (
        f"EXRs per case under {link(f'{fig}/exr/', f'{fig}/exr/')}"
        if have
        else f"EXRs per case ({code(f'{fig}/exr/<case>.exr')}) are not in this copy: `bash scripts/reproduce.sh` "
        "makes them"
    )
    return f"Per-case image viewer ({len(m['cases'])} cases): {link('index.html', f'index.html#viewers-{fig}')}; {exr}."


def _viewers_html(
    reports: Path, fig: str, manifests: dict, made: dict | None = None, heading: str | None = None, fold=False
) -> str:
    m = _figure_viewers(reports, fig, made)
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
    opened, closed = "", ""
    if fold:  # several figures on the page: each figure's viewers folded until the reader opens them
        opened = (
            f'<details class="viewers-box"><summary>{len(m["cases"])} image viewers (click to open)</summary>'
        )
        closed = "</details>"
    return (
        f'<h3 id="viewers-{esc(fig)}">{esc(heading or f"{fig}: images per case")}</h3>{opened}'
        '<p class="note">Click a viewer, then: '
        "number keys pick the image (the references first; digits typed quickly form one number, e.g. 1 2 for the "
        "12th) or ←/→, ↑/↓ the layer (image, angular error, outcome, …); r flips to truth_at_hit and back (A/B), "
        "d shows the difference from it; wheel or +/− to zoom (f: fit), drag to pan; the slider sets the exposure "
        "of the linear radiance (0 = as rendered, clipped at 1, sRGB). The viewers of a figure share exposure "
        f'and zoom.{note}</p><div class="viewers">{divs}</div>{closed}'
    )


def _luts() -> dict:
    """The colour maps the viewers use, 256 RGB entries each (matplotlib's)."""
    import matplotlib

    names = sorted({d["cmap"] for d in viewer.DISPLAY.values() if "cmap" in d})  # one order: same bytes
    return {
        n: [[round(255 * x) for x in matplotlib.colormaps[n](i / 255)[:3]] for i in range(256)] for n in names
    }


def _script_json(obj) -> str:
    """JSON to embed in a <script type="application/json">: no '</' that would end the element."""
    return json.dumps(obj, allow_nan=False).replace("</", "<\\/")


# ---------------------------------------------------------------------------------------------- the page
def page(blocks: list[tuple], reports: Path, *, title: str, made: dict | None = None) -> str:
    """The blocks as one HTML page (``index.html``); ``made``: figure → viewer manifest of files written together
    with the page (not yet on disk)."""
    body, toc, manifests = [], [], {}
    open_section = False  # each h2 and what follows it: one <section>
    fold = sum(b[0] == "viewer" for b in blocks) > 1  # several figures' viewers: each folded until opened
    for b in blocks:
        kind = b[0]
        if kind == "h":
            anchor = re.sub(r"[^a-z0-9]+", "-", b[2].lower()).strip("-")
            if b[1] == 2:
                toc.append(f'<a href="#{anchor}">{inline(b[2])}</a>')
                body.append("</section><section>" if open_section else "<section>")
                open_section = True
            body.append(f'<h{b[1]} id="{anchor}">{inline(b[2])}</h{b[1]}>')
        elif kind == "p":
            body.append(f"<p>{inline(b[1])}</p>")
        elif kind == "list":
            body.append("<ul>" + "".join(f"<li>{inline(t)}</li>" for t in b[1]) + "</ul>")
        elif kind == "table":
            t = table(b[1], b[2])
            if len(b[1]) > OPEN_ROWS:  # a long table (every case × method) folded: the page stays navigable
                n = len([c for c in b[2] if any(c in r for r in b[1])])
                head = f"{len(b[1])} rows × {n} columns (click to show)"
                t = f'<details class="long"><summary>{head}</summary>{t}</details>'
            body.append(t)
        elif kind == "img":
            src = esc(quote(b[1], safe="/"))
            body.append(f'<figure><a href="{src}"><img src="{src}" alt="{esc(b[2])}"></a></figure>')
        elif kind == "media":
            src = esc(quote(b[1], safe="/"))
            tag = (
                f'<video src="{src}" controls loop muted></video>'
                if b[1].endswith((".mp4", ".webm"))
                else f'<img src="{src}" alt="{esc(b[2])}">'
            )
            body.append(f'<figure>{tag}<figcaption><a href="{src}">{esc(b[1])}</a></figcaption></figure>')
        elif kind == "viewer":
            heading = (
                b[2] if len(b) > 2 else None
            )  # ("viewer", figure, heading): default "<figure>: images …"
            body.append(_viewers_html(reports, b[1], manifests, (made or {}).get(b[1]), heading, fold))
    if open_section:
        body.append("</section>")
    css = (_HERE / "html.css").read_text(encoding="utf-8")
    js = (_HERE / "viewer.js").read_text(encoding="utf-8")
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f"<title>{esc(title)}</title>",
            f"<style>{css}</style></head><body>",
            f'<nav class="toc">{" · ".join(toc)}</nav><main>' if toc else "<main>",  # no empty bar
            *body,
            "</main>",
            f'<script type="application/json" id="study-manifest">{_script_json(manifests)}</script>',
            f'<script type="application/json" id="study-luts">{_script_json(_luts() if manifests else {})}</script>',
            f"<script>{js}</script>",
            "</body></html>",
            "",
        ]
    )
