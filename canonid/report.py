"""A small report builder: headings, paragraphs, tables, figures and links, written both as
Markdown (figures linked by relative path) and as one self-contained HTML file (figures inlined).

    report = Report("canonid reproduction — tank, quick profile")
    report.heading("Table 1")
    report.table(["ℓ", "Ours (MLP)", "paper"], rows)
    report.figure(run_dir / "rollout.png", "100-step rollouts on test trajectories")
    md_path, html_path = report.write(out_dir)

Paths are stored as given and rendered relative to the folder the report is written to. Text
(paragraphs, headings, table cells, captions, link labels) may use Markdown's inline subset:
``**strong**``, ``*emphasis*`` and ```code```; the HTML renders it (:func:`inline_html`), the
Markdown keeps it as written. Figures are embedded in the HTML page (PNG and SVG as images, any
other file as a link).
"""

from __future__ import annotations

import base64
import html
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from canonid.kernel.io import atomic_write_text

__all__ = ["Report", "inline_html"]

#: a code span; what lies between two is text whose emphasis is rendered
_CODE = re.compile(r"`([^`]+)`")
_STRONG = re.compile(r"\*\*(?=\S)(.+?)(?<=\S)\*\*")
_EMPHASIS = re.compile(r"(?<![\w*])\*(?=[^\s*])(.+?)(?<=[^\s*])\*(?![\w*])")
#: the media type of a figure embedded in the page, by suffix
_IMAGE_TYPES = {".png": "image/png", ".svg": "image/svg+xml"}


def _plain(text: str) -> str:
    """``text`` without its Markdown marks, escaped (for a page title or an image's alt text)."""
    text = _CODE.sub(r"\1", text)
    return html.escape(_EMPHASIS.sub(r"\1", _STRONG.sub(r"\1", text)))


def inline_html(text: str) -> str:
    """``text`` (Markdown's inline subset: ``**strong**``, ``*emphasis*``, ```code```) as
    escaped HTML; a code span's content is shown as written, emphasis marks and all."""
    parts = []
    for i, piece in enumerate(_CODE.split(text)):
        escaped = html.escape(piece)
        if i % 2:
            parts.append(f"<code>{escaped}</code>")
        else:
            escaped = _STRONG.sub(r"<strong>\1</strong>", escaped)
            parts.append(_EMPHASIS.sub(r"<em>\1</em>", escaped))
    return "".join(parts)


@dataclass(frozen=True)
class _Heading:
    text: str
    level: int


@dataclass(frozen=True)
class _Paragraph:
    text: str


def _numeric(cell: str) -> bool:
    """Whether a table cell is a number (right-aligned in HTML, text left-aligned)."""
    try:
        float(cell.replace(",", "").strip())
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class _Table:
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    caption: str | None


@dataclass(frozen=True)
class _Figure:
    path: Path
    caption: str


@dataclass(frozen=True)
class _Link:
    path: Path
    label: str


@dataclass
class Report:
    """An ordered list of blocks rendered to Markdown and HTML."""

    title: str
    blocks: list[Any] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> None:
        if not 1 <= level <= 6:
            raise ValueError(f"heading level must be 1..6, got {level}")
        self.blocks.append(_Heading(text, level))

    def paragraph(self, text: str) -> None:
        self.blocks.append(_Paragraph(text))

    def table(
        self, header: Sequence[Any], rows: Sequence[Sequence[Any]], caption: str | None = None
    ) -> None:
        head = tuple(str(h) for h in header)
        body = tuple(tuple(str(c) for c in row) for row in rows)
        for i, row in enumerate(body):
            if len(row) != len(head):
                raise ValueError(f"table row {i} has {len(row)} cells, header has {len(head)}")
        self.blocks.append(_Table(head, body, caption))

    def figure(self, path: str | os.PathLike[str], caption: str) -> None:
        self.blocks.append(_Figure(Path(path), caption))

    def link(self, path: str | os.PathLike[str], label: str) -> None:
        self.blocks.append(_Link(Path(path), label))

    # ------------------------------------------------------------------ rendering
    @staticmethod
    def _rel(path: Path, base: Path) -> str:
        try:
            return Path(os.path.relpath(path.resolve(), base.resolve())).as_posix()
        except ValueError:  # another drive on Windows
            return path.resolve().as_posix()

    def to_markdown(self, base: str | os.PathLike[str]) -> str:
        base = Path(base)
        out = [f"# {self.title}", ""]
        for b in self.blocks:
            if isinstance(b, _Heading):
                out += ["#" * b.level + " " + b.text, ""]
            elif isinstance(b, _Paragraph):
                out += [b.text, ""]
            elif isinstance(b, _Table):
                esc = [[c.replace("|", "\\|") for c in row] for row in (b.header, *b.rows)]
                out.append("| " + " | ".join(esc[0]) + " |")
                out.append("|" + "|".join("---" for _ in b.header) + "|")
                out += ["| " + " | ".join(row) + " |" for row in esc[1:]]
                if b.caption:
                    out += ["", f"*{b.caption}*"]
                out.append("")
            elif isinstance(b, _Figure):
                out += [f"![{b.caption}]({self._rel(b.path, base)})", "", f"*{b.caption}*", ""]
            elif isinstance(b, _Link):
                out += [f"- [{b.label}]({self._rel(b.path, base)})", ""]
        return "\n".join(out).rstrip() + "\n"

    def to_html(self, base: str | os.PathLike[str]) -> str:
        base = Path(base)
        e, md = html.escape, inline_html
        parts = [
            "<!doctype html>",
            '<html lang="en"><head><meta charset="utf-8">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f"<title>{_plain(self.title)}</title>",
            "<style>body{font-family:sans-serif;max-width:64em;margin:2em auto;padding:0 1em;"
            "line-height:1.45}.wide{overflow-x:auto}table{border-collapse:collapse;margin:1em 0}"
            "td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}td.n{text-align:right}"
            "th{background:#f3f3f3}caption{caption-side:bottom;text-align:left;font-size:90%;"
            "color:#444;padding-top:4px}code{background:#f3f3f3;padding:0 3px}"
            "img{max-width:100%}figcaption{font-size:90%;color:#444}</style>",
            "</head><body>",
            f"<h1>{md(self.title)}</h1>",
        ]
        for b in self.blocks:
            if isinstance(b, _Heading):
                parts.append(f"<h{b.level}>{md(b.text)}</h{b.level}>")
            elif isinstance(b, _Paragraph):
                parts.append(f"<p>{md(b.text)}</p>")
            elif isinstance(b, _Table):
                parts.append('<div class="wide"><table>')
                if b.caption:
                    parts.append(f"<caption>{md(b.caption)}</caption>")
                parts.append(
                    "<thead><tr>" + "".join(f"<th>{md(c)}</th>" for c in b.header) + "</tr></thead>"
                )
                parts.append("<tbody>")
                parts += [
                    "<tr>"
                    + "".join(
                        f'<td class="n">{md(c)}</td>' if _numeric(c) else f"<td>{md(c)}</td>"
                        for c in r
                    )
                    + "</tr>"
                    for r in b.rows
                ]
                parts.append("</tbody></table></div>")
            elif isinstance(b, _Figure):
                parts.append(self._figure_html(b, base))
            elif isinstance(b, _Link):
                parts.append(f'<p><a href="{e(self._rel(b.path, base))}">{md(b.label)}</a></p>')
        parts.append("</body></html>")
        return "\n".join(parts) + "\n"

    def _figure_html(self, b: _Figure, base: Path) -> str:
        """A PNG or SVG figure embedded as an image; another file (a PDF) linked."""
        e = html.escape
        kind = _IMAGE_TYPES.get(b.path.suffix.lower())
        caption = f"<figcaption>{inline_html(b.caption)}</figcaption>"
        if kind is None:
            href = e(self._rel(b.path, base))
            return f'<figure><a href="{href}">{e(b.path.name)}</a>{caption}</figure>'
        if b.path.is_file():
            data = base64.b64encode(b.path.read_bytes()).decode("ascii")
            src = f"data:{kind};base64,{data}"
        else:
            src = e(self._rel(b.path, base))
        return f'<figure><img src="{src}" alt="{_plain(b.caption)}">{caption}</figure>'

    def write(self, folder: str | os.PathLike[str], name: str = "report") -> tuple[Path, Path]:
        """Write ``folder/name.md`` and ``folder/name.html`` atomically; return both paths."""
        folder = Path(folder)
        md = atomic_write_text(folder / f"{name}.md", self.to_markdown(folder))
        page = atomic_write_text(folder / f"{name}.html", self.to_html(folder))
        return md, page
