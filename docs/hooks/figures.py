"""Every measured figure of README.md and docs/, read from the record that measured it.

A record is a JSON file under ``benchmarks/`` (``records/*.json``, a study's record, a suite's
``suite.json``): command, commit, machine, load, ``figures`` and ``tables``. Two markers use it:
``7.52e-5<!-- figure: defaults/tank/0 -->`` after a quoted number (the quote must be the record's
value rounded to the digits shown, 7.52e-5 for 7.520165e-05; text must be equal; :data:`CODE`
keys quote a setting of the code), and ``<!-- table: records/NAME N -->`` on a line of its own,
replaced at build by the record's table N (a suite record: records × contestants and means)
and a line naming its command, commit, machine and load. As a MkDocs hook a disagreement is a
warning, which fails the strict build; ``tests/test_figures.py`` runs :func:`check`.
"""

from __future__ import annotations

import importlib
import json
import logging
import re
from collections.abc import Callable
from decimal import Decimal, InvalidOperation
from functools import cache, partial
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / "benchmarks"
MARKER = re.compile(r"<!-- figure: (?P<key>[\w./-]+) -->")
TABLE = re.compile(r"^<!-- table: (?P<name>[\w./-]+) (?P<nth>\d+) -->$", re.M)

log = logging.getLogger("mkdocs.plugins.figures")


def _get(module: str, name: str, *keys: Any) -> Any:
    value = getattr(importlib.import_module(module), name)
    for k in keys:
        value = value[k]
    return value


def _published(name: str, test: str, method: str) -> str:
    from canonid.datagen.benchmarks import benchmark

    (found, *_) = (
        b.figure for b in benchmark(name).baselines if (b.method, b.test) == (method, test)
    )
    return str(found)


QUICK_TRAIN = "epochs weight_decay horizon val_horizon batch_size lr windows_per_epoch".split()
#: settings of the code a page quotes (not measurements): key -> how to read it
CODE: dict[str, Callable[[], Any]] = {
    **{
        f"quick/train/{k}": partial(_get, "canonid.profiles", "PROFILES", "quick", "train", k)
        for k in QUICK_TRAIN
    },
    "code/feedthrough-gain": partial(_get, "canonid.learning.linear", "FEEDTHROUGH_GAIN"),
    "code/pool-min-steps": partial(_get, "canonid.jobs", "POOL_MIN_STEPS"),
    "code/horizon-check-k": partial(_get, "canonid.horizon_check", "CHECK_K"),
    "code/horizon-alternative/first": partial(_get, "canonid.horizon_check", "ALTERNATIVES", 0),
    "code/horizon-alternative/second": partial(_get, "canonid.horizon_check", "ALTERNATIVES", 1),
    "code/noted-beyond": lambda: f"{100 * _get('canonid.coverage', 'NOTED_BEYOND'):g}",
    "code/unvalidated-share": lambda: f"{100 * _get('canonid.coverage', 'UNVALIDATED_SHARE'):g}",
    "device/threshold": lambda: _get("canonid.learning.training", "AUTO_CUDA_WORK") / 1e6,
    "silverbox/published-gru": partial(_published, "silverbox", "multisine", "GRU"),
}


@cache
def records() -> dict[str, dict[str, Any]]:
    """Every record under benchmarks/ by its path there without ``.json``."""
    found = {}
    for path in sorted(BENCHMARKS.rglob("*.json")):
        body = json.loads(path.read_text(encoding="utf-8"))
        suite = isinstance(body, dict) and {"records", "contestants", "means"} <= set(body)
        if isinstance(body, dict) and ("figures" in body or "tables" in body or suite):
            found[path.relative_to(BENCHMARKS).with_suffix("").as_posix()] = body
    return found


@cache
def _figures() -> dict[str, tuple[str, str]]:
    """key -> (its value: a table cell's, kept by the writer, or text; its record), once."""
    held: dict[str, tuple[str, str]] = {}
    for name, record in records().items():
        for key, value in record.get("figures", {}).items():
            if key in held:
                raise ValueError(f"figure {key!r} in both {held[key][1]} and {name}")
            held[key] = (str(value["value"] if isinstance(value, dict) else value), name)
    return held


def value(key: str) -> str:
    """The value of ``key`` (KeyError naming what is missing)."""
    if key in CODE:
        return str(CODE[key]())
    if key not in _figures():
        raise KeyError(f"no figure {key!r} in any record under benchmarks/")
    return _figures()[key][0]


def _pair(rmse: float | None, cpu: float | None, finite: bool = True) -> list[str]:
    """A suite cell: RMSE (or "not finite") and CPU seconds; "—" where a run has none."""
    fmt = lambda v, spec: "—" if v is None else format(v, spec)  # noqa: E731
    return [fmt(rmse, ".4g") if finite else "not finite", fmt(cpu, ".0f")]


def _suite_table(record: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """A suite record as one table: a row per record and the means, RMSE and CPU s per
    contestant."""
    who, means = list(record["contestants"]), record["means"]
    columns = ["record", *(f"{w} {what}" for w in who for what in ("RMSE", "CPU s"))]
    rows = [
        [name, *(x for w in who for x in _pair(c[w]["rmse"], c[w]["cpu_seconds"], c[w]["finite"]))]
        for name, c in record["records"].items()
    ]
    total = (x for w in who for x in _pair(means[w]["rmse_geomean"], means[w]["cpu_seconds"]))
    return columns, [*rows, ["geometric mean RMSE, total CPU s", *total]]


def table(name: str, nth: int = 0) -> tuple[list[str], list[list[str]]]:
    """Table ``nth`` of record ``name``: (columns, rows of cells)."""
    record = records().get(name)
    if record is None:
        raise KeyError(f"no record {name!r} under benchmarks/")
    if "tables" not in record:
        return _suite_table(record)
    chosen = record["tables"][nth]
    return list(chosen["columns"]), [[str(c) for c in row] for row in chosen["rows"]]


def render(name: str, nth: int = 0) -> str:
    """Table ``nth`` of record ``name`` in Markdown, with what measured it."""
    columns, rows = table(name, nth)

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    record = records()[name]
    about = ", ".join(
        f"{what}: {record[what]}" for what in ("commit", "machine", "load") if record.get(what)
    )
    command = f"`{record['command']}`" if record.get("command") else "not stated"
    caption = f"*Record `benchmarks/{name}.json`; command: {command}; {about}.*"
    return "\n".join([line(columns), line(["---"] * len(columns)), *map(line, rows), "", caption])


def expand(text: str) -> str:
    """``text`` with every table marker replaced by its rendered table."""
    return TABLE.sub(lambda m: render(m["name"], int(m["nth"])), text)


def _number(text: str) -> Decimal | None:
    try:  # "−0.5", "9,000", "1.2;"
        return Decimal(text.replace("−", "-").replace(",", "").rstrip(".;:"))
    except InvalidOperation:
        return None


def agrees(quoted: str, source: str) -> bool:
    """Whether ``quoted`` is ``source`` rounded to the digits it shows (or, for text, equal)."""
    q, s = _number(quoted), _number(source)
    if q is None or s is None:
        return quoted == source
    half_unit = Decimal(1).scaleb(q.as_tuple().exponent) / 2
    return abs(q - s) <= half_unit * (1 + Decimal("1e-9"))


def check(text: str, where: str) -> list[str]:
    """One line per marker of ``text`` whose quote disagrees with its record (or has none)."""
    problems = []
    for match in TABLE.finditer(text):
        try:
            table(match["name"], int(match["nth"]))
        except (KeyError, IndexError) as err:
            problems.append(f"{where}: table {match['name']} {match['nth']}: {err!r}")
    for match in MARKER.finditer(text):
        key, line = match["key"], text.count("\n", 0, match.start()) + 1
        try:
            expected = value(key)
        except KeyError as err:
            problems.append(f"{where}:{line}: {err.args[0]}")
            continue
        before = text[: match.start()]
        if _number(expected) is None:
            ok, quoted = before.endswith(expected), before[-len(expected) - 10 :].strip()
        else:
            quoted = re.split(r"[\s(|/*`=×]", before.rstrip())[-1]
            ok = agrees(quoted, expected)
        if not ok:
            problems.append(f"{where}:{line}: {quoted!r} quotes {key}, its record: {expected}")
    return problems


def on_page_markdown(markdown: str, page: Any, **_: Any) -> str:
    """Warn (a failure of the strict build) for every quote that disagrees; render the tables."""
    for problem in check(markdown, page.file.src_path):
        log.warning(problem)
    return expand(markdown)
