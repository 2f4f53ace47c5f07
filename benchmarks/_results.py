"""Write one benchmark's section of ``benchmarks/RESULTS.md``, leaving the others untouched.

Each script owns the text between ``<!-- BEGIN name -->`` and ``<!-- END name -->``; the
section starts with the command, the date and a description of the machine. Notes a person added
to a section (from its first line beginning :data:`HAND_NOTE`) stay, after the new text, when the
script writes the section again.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import re
import sys
from pathlib import Path

from canonid.kernel.io import atomic_write_text

RESULTS = Path(__file__).resolve().parent / "RESULTS.md"
#: how a note written by a person into a section begins (dated: what run it speaks of)
HAND_NOTE = "Added by hand"

__all__ = [
    "HAND_NOTE",
    "append_row",
    "load_line",
    "machine_description",
    "publish",
    "read_rows",
    "record",
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


def write_section(name: str, body: str, *, command: str | None = None) -> None:
    """Replace (or append) section ``name`` of RESULTS.md with ``body`` (Markdown), keeping the
    section's hand notes after it."""
    cmd = command or "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    text = RESULTS.read_text(encoding="utf-8") if RESULTS.exists() else "# Benchmark results\n"
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
    text = pattern.sub(lambda _: block, text) if old else text.rstrip() + "\n\n" + block + "\n"
    atomic_write_text(RESULTS, text)


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
