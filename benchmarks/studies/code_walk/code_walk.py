"""Code walk: the modules one training option passes through, from the parser to the optimiser.

Runs ``canonid train`` (in this process, on a small CSV written to a temporary folder) with
``--lr`` set to an unusual value and records through :func:`sys.setprofile` every function of
``canonid`` called with that value among its arguments: itself, or inside a mapping, a sequence,
a dataclass or an argparse namespace, up to four levels deep, until a ``torch.optim`` optimiser
is built with it. The modules of those functions, in the order first entered, are the walk; the
last builds the optimiser. What the value passes through after that (the history, the figures,
the summary printed) is not counted.

``--baseline REF`` walks the tree of git revision ``REF`` too (exported to a temporary folder,
run by the same interpreter in a child process). Writes the "Code walk" section of
its notes (``benchmarks/records/``) with both lists.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/

#: the learning rate given: a value no default or computation produces by chance
SENTINEL = 0.000123456789
#: how deep the arguments are searched for it
DEPTH = 4


def _holds(value: Any, depth: int = DEPTH) -> bool:
    """Whether ``value`` is the sentinel or holds it (``depth`` levels of containers)."""
    if isinstance(value, float):
        return value == SENTINEL
    if depth == 0 or isinstance(value, str | bytes | type):
        return False
    if isinstance(value, argparse.Namespace):
        value = vars(value)
    elif dataclasses.is_dataclass(value):
        value = {f.name: getattr(value, f.name, None) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return any(_holds(v, depth - 1) for v in list(value.values())[:64])
    if isinstance(value, list | tuple):
        return any(_holds(v, depth - 1) for v in value[:64])
    return False


def walk(data: Path, out: Path) -> list[dict[str, Any]]:
    """The modules (with their functions) that the sentinel ``--lr`` enters, in order."""
    from canonid.cli import main

    seen: dict[str, list[str]] = {}
    reached: list[str] = []

    def profile(frame: Any, event: str, arg: Any) -> None:
        if event != "call" or reached:
            return
        module = frame.f_globals.get("__name__", "")
        if module.startswith("torch.optim") and frame.f_code.co_name == "__init__":
            if _holds(frame.f_locals.get("lr")):
                reached.append(module)
            return
        if not module.startswith("canonid"):
            return
        code = frame.f_code
        names = code.co_varnames[: code.co_argcount + code.co_kwonlyargcount]
        if any(_holds(frame.f_locals.get(n)) for n in names):
            functions = seen.setdefault(module, [])
            if code.co_name not in functions:
                functions.append(code.co_name)

    argv = ["train", str(data), "--inputs", "u", "--outputs", "y", "--dt", "0.1", "--window"]
    argv += ["2", "--epochs", "1", "--lr", repr(SENTINEL), "--out", str(out), "--no-progress"]
    argv += ["--device", "cpu", "--threads", "1", "--model", "mlp", "--hidden", "8"]
    sys.setprofile(profile)
    try:
        status = main(argv)
    finally:
        sys.setprofile(None)
    if status != 0 or not reached:
        raise SystemExit(f"canonid train failed ({status}) or built no optimiser with --lr")
    return [{"module": m, "functions": f} for m, f in seen.items()]


def _csv(folder: Path) -> Path:
    path = folder / "walk.csv"
    rows = [f"{0.1 * (t % 7):.3f},{0.05 * (t % 11):.3f}" for t in range(200)]
    path.write_text("u,y\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _child(tree: Path, scratch: Path) -> list[dict[str, Any]]:
    """The walk of ``tree`` in a fresh interpreter that imports canonid from it."""
    from bench_startup import importable_tree

    path = importable_tree(tree, scratch)
    code = (
        f"import json, sys; sys.path[:0] = [{str(path)!r}, {str(Path(__file__).parent)!r}]; "
        "import code_walk as w; from pathlib import Path; "
        f"print(json.dumps(w.walk(w._csv(Path({str(scratch)!r})), Path({str(scratch / 'run')!r}))))"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=scratch
    )
    return json.loads(res.stdout.strip().splitlines()[-1])


def _table(steps: list[dict[str, Any]]) -> str:
    rows = [
        f"| {i} | `{s['module']}` | {', '.join(f'`{f}`' for f in s['functions'])} |"
        for i, s in enumerate(steps, 1)
    ]
    return "\n".join(["| # | module | functions called with the value |", "|---|---|---|", *rows])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", metavar="REF", help="also walk git revision REF")
    parser.add_argument(
        "--no-write", action="store_true", help="print, do not write the record's notes"
    )
    args = parser.parse_args()
    cpu0 = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp)
        now = walk(_csv(scratch), scratch / "run")
        walks = {"this tree": now}
        if args.baseline:
            from bench_startup import export_tree

            (scratch / "old").mkdir()
            old = export_tree(args.baseline, scratch / "baseline")
            walks = {f"`{args.baseline}`": _child(old, scratch / "old"), **walks}
    parts = [
        f"`--lr` from `canonid train`'s command line to the optimiser: the modules of `canonid` "
        f"whose functions are called with its value (the walk, in the order first entered; "
        f"traced with `sys.setprofile` on a 200-row CSV, one epoch). Load: "
        f"{' / '.join(f'{v:.2f}' for v in __import__('os').getloadavg())}; CPU "
        f"{time.process_time() - cpu0:.1f} s in this process; device: CPU."
    ]
    for label, steps in walks.items():
        parts += ["", f"**{label}**: {len(steps)} modules", "", _table(steps)]
    body = "\n".join(parts)
    print(body)
    if not args.no_write:
        from _results import write_section

        write_section("Code walk", body)
    return 0


if __name__ == "__main__":
    sys.exit(main())
