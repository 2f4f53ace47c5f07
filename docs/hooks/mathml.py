"""MkDocs hook: TeX between dollars becomes MathML when the site is built.

``$…$`` (inline) and ``$$…$$`` (display) in the prose of a page are converted by latex2mathml (a
PyPI package, so nothing is fetched when a page is viewed and the site reads the same offline);
browsers render MathML natively. Code (fenced blocks and inline spans) and HTML comments, where
the snippets and their markers live, are left exactly as written. An inline formula opens on a
``$`` followed by a non-space and closes on a non-space followed by ``$`` (it may span lines,
not paragraphs), so prices and shell variables in prose need no escaping.
"""

from __future__ import annotations

import re
from typing import Any

# Everything that is not prose: fenced blocks (``` or ~~~, any indentation, to the matching
# fence), inline code spans, HTML comments. Prose is what lies between the matches.
_CODE = re.compile(
    r"(?P<fence>^[ \t]*(?P<mark>`{3,}|~{3,})[^\n]*\n.*?^[ \t]*(?P=mark)[ \t]*$)"
    r"|(?P<span>(?P<ticks>`+).+?(?P=ticks))"
    r"|(?P<comment><!--.*?-->)",
    re.M | re.S,
)
_DISPLAY = re.compile(r"\$\$(.+?)\$\$", re.S)
_INLINE = re.compile(r"(?<![\\$\w])\$(?=\S)((?:[^$\n]|\n(?![ \t]*\n))+?)(?<=\S)\$(?![\w$])")


def _mathml(tex: str, display: str) -> str:
    from latex2mathml.converter import convert

    # a pipe inside a table row would end the cell: write it as an entity
    return convert(tex.strip(), display=display).replace("|", "&#124;")


def _prose(text: str) -> str:
    text = _DISPLAY.sub(
        lambda m: f'\n\n<div class="math-display">{_mathml(m.group(1), "block")}</div>\n\n',
        text,
    )
    # in a span: Python-Markdown takes a line that starts with <math> for an HTML block
    return _INLINE.sub(lambda m: f'<span class="math">{_mathml(m.group(1), "inline")}</span>', text)


def render(markdown: str) -> str:
    """``markdown`` with every formula of its prose written as MathML."""
    out, last = [], 0
    for match in _CODE.finditer(markdown):
        out += [_prose(markdown[last : match.start()]), match.group(0)]
        last = match.end()
    out.append(_prose(markdown[last:]))
    return "".join(out)


def on_page_markdown(markdown: str, **_: Any) -> str:
    """Convert the page's formulas (MkDocs ``on_page_markdown`` event)."""
    return render(markdown)
