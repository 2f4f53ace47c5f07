"""Griffe extension: the docstrings' reST habits, read as Google-style Markdown by the API pages.

The code's docstrings cite other objects with Sphinx roles (``:func:`fit```), mark literal text
with double backquotes, close a paragraph with ``::`` before a literal block, and describe
related arguments on one line (``X, U: boxes for x and u.``). The first three become Markdown
(inline code, a single colon); a grouped argument line becomes one entry per name with the same
text, so griffe still checks every name against the signature. Nothing else changes.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?[a-z]+:`~?([^`]+)`")
_DOUBLE = re.compile(r"``([^`]+)``")
_LITERAL_BLOCK = re.compile(r"::$", re.MULTILINE)
_SECTION = re.compile(r"^(\s*)(Args|Arguments|Parameters|Attributes):\s*$")
_GROUPED = re.compile(r"^(\s+)(\w+(?:,\s*\w+)+)(\s*\([^)]*\))?:(.*)$")


def _split_grouped_arguments(text: str) -> str:
    out: list[str] = []
    section_indent: int | None = None
    for line in text.splitlines():
        header = _SECTION.match(line)
        if header:
            section_indent = len(header.group(1))
        elif line.strip() and section_indent is not None:
            if len(line) - len(line.lstrip()) <= section_indent:
                section_indent = None
        grouped = _GROUPED.match(line) if section_indent is not None else None
        if grouped:
            indent, names, kind, rest = grouped.groups()
            out += [f"{indent}{n.strip()}{kind or ''}:{rest}" for n in names.split(",")]
        else:
            out.append(line)
    return "\n".join(out)


def markdown(text: str) -> str:
    """``text`` with the reST habits above rewritten as Google-style Markdown."""
    text = _DOUBLE.sub(r"`\1`", _ROLE.sub(r"`\1`", text))
    return _split_grouped_arguments(_LITERAL_BLOCK.sub(":", text))


class ReSTHabits(griffe.Extension):
    """Rewrite each object's docstring when it is created (packages included) and once the tree
    is loaded; the rewrite is idempotent."""

    def _rewrite(self, obj: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown(obj.docstring.value)

    def on_instance(self, *, obj: Any, **kwargs: Any) -> None:
        self._rewrite(obj)

    def on_object(self, *, obj: Any, **kwargs: Any) -> None:
        self._rewrite(obj)
