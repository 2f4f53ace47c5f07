"""Write one benchmark's notes, the Markdown beside its JSON record, leaving the others untouched.

Each section ``name`` lives in one file, ``SLUG.md`` beside the record ``SLUG.json`` (in
``benchmarks/records/`` or a study's folder; a new one in ``benchmarks/records/``; SLUG is the
name in lower case, runs of other characters as ``-``). Each script owns the text between
``<!-- BEGIN name -->`` and ``<!-- END name -->``; the section starts with the command, the date
and a description of the machine. Notes a person added
to a section (from its first line beginning :data:`HAND_NOTE`) stay, after the new text, when the
script writes the section again.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

from canonid.kernel.io import atomic_write_text

#: the folder whose records and notes the scripts write (tests point it elsewhere)
BENCHMARKS = Path(__file__).resolve().parent
#: how a note written by a person into a section begins (dated: what run it speaks of)
HAND_NOTE = "Added by hand"

__all__ = [
    "HAND_NOTE",
    "append_row",
    "cell_value",
    "load_line",
    "machine_description",
    "publish",
    "read_rows",
    "read_section",
    "record",
    "tables_of",
    "update_record",
    "write_section",
]


def machine_description() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
        mem = f", {kb / 2**20:.0f} GiB RAM"
    except (OSError, ValueError, IndexError):
        pass
    return (
        f"{os.cpu_count()} cores ({cpu}){mem}, {platform.system()} {platform.release()}, "
        f"Python {platform.python_version()}"
    )


def section_file(name: str) -> Path:
    """The notes file of section ``name``: beside its record where one exists, else new in
    ``records/``."""
    slug = re.sub(r"[^a-z0-9]+", "-", name.lower()).strip("-")
    found = sorted(BENCHMARKS.rglob(f"{slug}.md"))
    return found[0] if found else BENCHMARKS / "records" / f"{slug}.md"


def read_section(name: str) -> str:
    """The text of section ``name`` (its markers included), or "" when none is written."""
    path = section_file(name)
    return path.read_text(encoding="utf-8") if path.exists() else ""


def write_section(name: str, body: str, *, command: str | None = None) -> None:
    """Replace section ``name`` with ``body`` (Markdown), keeping the section's hand notes after
    it."""
    cmd = command or "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    path = section_file(name)
    text = read_section(name)
    pattern = re.compile(
        rf"<!-- BEGIN {re.escape(name)} -->.*?<!-- END {re.escape(name)} -->", re.S
    )
    old = pattern.search(text)
    notes = re.search(rf"^{HAND_NOTE}.*(?=^<!-- END )", old.group(0), re.S | re.M) if old else None
    block = (
        f"<!-- BEGIN {name} -->\n"
        f"## {name}\n\n"
        f"Command: `{cmd}` — {stamp} — {machine_description()}\n\n"
        f"{body.strip()}\n" + (notes.group(0) if notes else "") + f"<!-- END {name} -->"
    )
    text = pattern.sub(lambda _: block, text) if old else block + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, text)
    update_record(name, block, command=cmd, date=stamp)


def tables_of(text: str) -> list[dict[str, list]]:
    """The Markdown tables of ``text``: ``{"columns": [...], "rows": [[...], ...]}`` each."""
    tables, lines = [], text.splitlines()
    for i, line in enumerate(lines):
        if i + 1 < len(lines) and line.startswith("|") and re.match(r"^\|[-:| ]+\|$", lines[i + 1]):
            rows = []
            for row in lines[i + 2 :]:
                if not row.startswith("|"):
                    break
                rows.append(_cells(row))
            tables.append({"columns": _cells(line), "rows": rows})
    return tables


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def _is_number(word: str) -> bool:
    try:
        float(word.replace("−", "-").replace(",", "").rstrip(".;:"))
    except ValueError:
        return False
    return True


def cell_value(tables: list[dict[str, list]], figure: dict[str, Any]) -> str:
    """The figure a record's ``figures`` entry points at: in table ``table``, the row whose cells
    match ``row``, column ``column``: its first word (``pick``: the number at that place among
    the cell's numbers; ``whole``: the whole cell), bold and the best-published mark dropped."""
    table = tables[figure["table"]]
    for cells in table["rows"]:
        found = dict(zip(table["columns"], cells))
        if all(found.get(k) == v for k, v in figure["row"].items()):
            text = found[figure["column"]].replace("**", "").strip().rstrip("*")
            if figure.get("whole"):
                return text
            numbers = [w for w in (w.strip("();") for w in text.split()) if _is_number(w)]
            return numbers[figure["pick"]] if figure.get("pick") else text.split()[0]
    raise KeyError(f"no row {figure['row']} with a column {figure['column']!r}")


def _commit() -> str:
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=BENCHMARKS, capture_output=True, text=True
        )
    except OSError:
        return "unknown"
    return out.stdout.strip() or "unknown"


def update_record(name: str, block: str, *, command: str, date: str) -> Path:
    """Write section ``name``'s JSON record beside its notes: the command, commit, date, machine
    and load of this run, every table of ``block`` cell by cell, and each figure the docs quote
    from a table read again from its cell (a figure typed as text stays as it is)."""
    path = section_file(name).with_suffix(".json")
    old = json.loads(path.read_text(encoding="utf-8")) if path.exists() else {}
    tables = tables_of(block)
    figures = {
        key: {**f, "value": cell_value(tables, f)} if isinstance(f, dict) else f
        for key, f in old.get("figures", {}).items()
    }
    load = re.search(r"[Ll]oad average.*?(?=\.\s|\.$|\n|$)", block)  # its sentence
    record = {
        "study": name,
        "source": f"written by the script, section notes in {path.with_suffix('.md').name}",
        "command": command,
        "commit": _commit(),
        "date": date,
        "machine": machine_description(),
        "load": load.group(0) if load else None,
        "figures": figures,
        "tables": tables,
    }
    atomic_write_text(path, json.dumps(record, indent=1, ensure_ascii=False) + "\n")
    return path


def read_rows(path: Path) -> list[dict]:
    """The rows of a study's JSON-lines file."""
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line]


def append_row(path: Path, row: dict) -> None:
    """Append one row to a study's JSON-lines file (a row is one write of one line)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a", encoding="utf-8") as f:
        f.write(json.dumps(row) + "\n")
    print(json.dumps(row))


def record(name: str, body: str) -> int:
    """Write ``body`` as section ``name`` and print it; 0 (a study's last step)."""
    write_section(name, body)
    print(body)
    return 0


def publish(name: str, lines: list[str], minutes: float) -> int:
    """Write ``lines`` and how long the benchmark took as section ``name``, print them; 0."""
    body = "\n".join([*lines, "", f"This benchmark took {minutes:.1f} min."])
    write_section(name, body)
    print(body)
    return 0


def load_line(load: list[float], caveat: str, own: list[int] | None = None) -> tuple[str, bool]:
    """The sentence giving the 1-minute load averages ``load`` (at the start and after each
    part) and whether other jobs loaded the machine: a reading more than 1 above ``own``, the
    benchmark's own busy processes in the part it follows (default none), since a part run on
    2 workers raises the load to about 2 by itself; then ``caveat`` says in bold what the load
    means for the figures."""
    own = own or [0] * len(load)
    loaded = max(v - o for v, o in zip(load, own, strict=True)) > 1.0
    values = " / ".join(f"{v:.2f}" for v in load)
    mine = (
        ""
        if not any(own)
        else f" (this benchmark's own busy processes: {' / '.join(map(str, own))})"
    )
    return (
        f"Load average (1 min) at the start and after each part: {values}{mine}, on 2 cores "
        + (f"**shared with other jobs ({caveat})**." if loaded else "(idle)."),
        loaded,
    )
