"""A small report builder: headings, paragraphs, tables, figures and links, written both as
Markdown (figures linked by relative path) and as one self-contained HTML file (figures inlined).

    report = Report("canonid reproduction — tank, quick profile")
    report.heading("Table 1")
    report.table(["ℓ", "Ours (MLP)", "paper"], rows)
    report.figure(run_dir / "rollout.png", "100-step rollouts on test trajectories")
    md_path, html_path = report.write(out_dir)

Paths are stored as given and rendered relative to the folder the report is written to.
"""

from __future__ import annotations

import base64
import html
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from canonid.kernel.io import atomic_write_text

__all__ = ["Report"]


@dataclass(frozen=True)
class _Heading:
    text: str
    level: int


@dataclass(frozen=True)
class _Paragraph:
    text: str


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
        e = html.escape
        parts = [
            "<!doctype html>",
            '<html><head><meta charset="utf-8">',
            f"<title>{e(self.title)}</title>",
            "<style>body{font-family:sans-serif;max-width:60em;margin:2em auto;}"
            "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px;"
            "text-align:right}img{max-width:100%}</style>",
            "</head><body>",
            f"<h1>{e(self.title)}</h1>",
        ]
        for b in self.blocks:
            if isinstance(b, _Heading):
                parts.append(f"<h{b.level}>{e(b.text)}</h{b.level}>")
            elif isinstance(b, _Paragraph):
                parts.append(f"<p>{e(b.text)}</p>")
            elif isinstance(b, _Table):
                parts.append("<table>")
                if b.caption:
                    parts.append(f"<caption>{e(b.caption)}</caption>")
                parts.append("<tr>" + "".join(f"<th>{e(c)}</th>" for c in b.header) + "</tr>")
                parts += ["<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in b.rows]
                parts.append("</table>")
            elif isinstance(b, _Figure):
                if b.path.is_file():
                    data = base64.b64encode(b.path.read_bytes()).decode("ascii")
                    src = f"data:image/png;base64,{data}"
                else:
                    src = e(self._rel(b.path, base))
                parts.append(
                    f'<figure><img src="{src}" alt="{e(b.caption)}">'
                    f"<figcaption>{e(b.caption)}</figcaption></figure>"
                )
            elif isinstance(b, _Link):
                parts.append(f'<p><a href="{e(self._rel(b.path, base))}">{e(b.label)}</a></p>')
        parts.append("</body></html>")
        return "\n".join(parts) + "\n"

    def write(self, folder: str | os.PathLike[str], name: str = "report") -> tuple[Path, Path]:
        """Write ``folder/name.md`` and ``folder/name.html`` atomically; return both paths."""
        folder = Path(folder)
        md = atomic_write_text(folder / f"{name}.md", self.to_markdown(folder))
        page = atomic_write_text(folder / f"{name}.html", self.to_html(folder))
        return md, page
