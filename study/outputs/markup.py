"""The report's text, safe whatever the names in it: Markdown for ``index.md``, HTML for ``index.html``.

Names (cases, methods, configs, files) are data, never markup: :func:`md_esc` backslash-escapes them for Markdown
(a ``<script>`` or ``[x](javascript:…)`` in a case name stays text in any Markdown viewer), :func:`inline` turns
the report's own inline Markdown into HTML with every character escaped, and links only to the report's own files
by relative paths (:func:`own_href`): a ``javascript:``, ``data:`` or ``http:`` link, an absolute path or ``..``
stays text. Table cells are plain text unless the report wrote them as Markdown (:class:`Md`).
"""

from __future__ import annotations

import html as _html
import re
from urllib.parse import quote

#: ASCII punctuation a name may carry that Markdown would read as syntax (CommonMark backslash escapes).
_MD_SPECIAL = re.compile(r"([\\`*_\[\]()<>|!#&{}])")
_ESCAPED = re.compile(r"\\([!-/:-@\[-`{-~])")


class Md(str):
    """Text the report wrote as Markdown (a table cell rendered with :func:`inline`, not escaped)."""


def esc(s) -> str:
    return _html.escape(str(s), quote=True)


def md_esc(s) -> str:
    """``s`` as literal Markdown text: its punctuation backslash-escaped, line breaks as spaces."""
    return _MD_SPECIAL.sub(r"\\\1", " ".join(str(s).splitlines()))


def code(s) -> str:
    """``s`` as an inline code span (a name with a backtick: escaped text instead)."""
    s = " ".join(str(s).splitlines())
    return f"`{s}`" if "`" not in s and s.strip() else md_esc(s)


def own_href(path: str) -> bool:
    """Whether ``path`` is a link to the report's own files: relative, no scheme, no ``..``, no quotes."""
    return bool(
        path
        and not re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", path)
        and not path.startswith(("/", "\\"))
        and ".." not in path.split("#")[0].split("/")
        and not re.search(r"[\s\"'<>`\\]", path)
    )


def link(text, path: str) -> str:
    """A Markdown link to a file of the report (``path`` relative to it, percent-encoded)."""
    return f"[{md_esc(text)}]({quote(str(path), safe='/#')})"


def inline(md: str) -> str:
    """The inline Markdown the report writes (`code`, **strong**, *emphasis*, [text](link), backslash escapes) as
    HTML; a link that is not to the report's own files (:func:`own_href`) stays text."""
    held: list[str] = []

    def hold(html_text: str) -> str:
        held.append(html_text)
        return f"\x00{len(held) - 1}\x00"

    text = _ESCAPED.sub(lambda m: hold(esc(m.group(1))), str(md).replace("\x00", ""))
    parts, out = text.split("`"), []
    if len(parts) % 2 == 0:  # an unmatched backtick is text
        parts[-2:] = [parts[-2] + "`" + parts[-1]]
    for i, part in enumerate(parts):  # code spans held first, so that **bold `code` text** spans them
        out.append(hold(f"<code>{esc(_restore(part, held, raw=True))}</code>") if i % 2 else esc(part))
    t = re.sub(
        r"\[([^\]]+)\]\(([^)\s]+)\)",
        lambda m: (
            f'<a href="{m.group(2)}">{m.group(1)}</a>' if own_href(_html.unescape(m.group(2))) else m.group(0)
        ),
        "".join(out),
    )
    t = re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", t)
    t = re.sub(r"(?<![\w*])\*([^*\s][^*]*?)\*(?![\w*])", r"<em>\1</em>", t)
    return _restore(t, held)


def _restore(s: str, held: list[str], raw: bool = False) -> str:
    def back(m):
        h = held[int(m.group(1))]
        return _html.unescape(h) if raw else h

    for _ in range(3):  # code spans hold escapes; the page holds code spans
        s = re.sub(r"\x00(\d+)\x00", back, s)
    return s
