"""Find and run the code snippets of the Markdown documentation (README.md and docs/).

A fenced block whose info string starts with ``python`` runs in this interpreter; one that starts
with ``bash`` or ``sh`` runs in ``bash -euo pipefail`` with the interpreter's ``bin`` folder first
on ``PATH`` (so ``canonid`` and ``python`` are the installed ones). Every block of a page runs in
document order in one scratch folder, with one Python namespace per page, so a block may use what
an earlier one made. Two HTML comments, invisible on the site, steer the runner:

* ``<!-- snippet: not-run — REASON -->`` on the line before a block: the block is not run; the
  reason is required (e.g. the command takes minutes, or needs a download).
* ``<!-- snippet-setup: bash`` (or ``python``), then code, then ``-->``: code run at that point
  and not shown, e.g. to make the small dataset a page's examples read.

Every other fenced block needs a language (``text`` for output, ``json``, ...), so no shell or
Python snippet can escape by having none.
"""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys
import types
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

RUNNABLE = {"python": "python", "py": "python", "bash": "bash", "sh": "bash"}
_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})(?P<info>.*)$")
_NOT_RUN = re.compile(r"^\s*<!--\s*snippet:\s*not-run\s*(?:—|-)+\s*(?P<reason>.*?)\s*-->\s*$")
_MARKER = re.compile(r"^\s*<!--\s*snippet")
_SETUP = re.compile(r"^\s*<!--\s*snippet-setup:\s*(?P<lang>python|bash)\s*$")
BASH_TIMEOUT_S = 300


class SnippetError(Exception):
    """A snippet failed, or a page's markup breaks the rules above."""


@dataclass(frozen=True)
class Snippet:
    """One runnable block: where it is, its language, its code and why it is not run (if so)."""

    path: Path
    line: int  # 1-based line of the opening fence (or of the setup comment)
    lang: str  # "python" or "bash"
    code: str
    not_run: str | None = None
    hidden: bool = False

    @property
    def where(self) -> str:
        return f"{self.path}:{self.line}"


def snippets(path: Path) -> list[Snippet]:
    """Every runnable block and hidden setup of the Markdown file ``path``, in order."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found: list[Snippet] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        setup = _SETUP.match(line)
        if setup:
            end = next((j for j in range(i + 1, len(lines)) if "-->" in lines[j]), None)
            if end is None:
                raise SnippetError(f"{path}:{i + 1}: snippet-setup comment is never closed")
            code = "\n".join([*lines[i + 1 : end], lines[end].split("-->")[0]]).strip() + "\n"
            found.append(Snippet(path, i + 1, setup.group("lang"), code, hidden=True))
            i = end + 1
            continue
        if _MARKER.search(line) and not _NOT_RUN.match(line):
            raise SnippetError(
                f"{path}:{i + 1}: unreadable snippet marker {line.strip()!r}; expected "
                "'<!-- snippet: not-run — REASON -->' or '<!-- snippet-setup: bash|python'"
            )
        fence = _FENCE.match(line)
        if not fence:
            i += 1
            continue
        indent, mark, info = fence.group("indent"), fence.group("fence"), fence.group("info")
        lang = info.strip().split(" ")[0].split("{")[0].lower()
        if not lang:
            raise SnippetError(f"{path}:{i + 1}: fenced block without a language (use text?)")
        close = re.compile(rf"^[ \t]*{re.escape(mark[0])}{{{len(mark)},}}\s*$")
        end = next((j for j in range(i + 1, len(lines)) if close.match(lines[j])), None)
        if end is None:
            raise SnippetError(f"{path}:{i + 1}: fenced block is never closed")
        if lang in RUNNABLE:
            body = [ln[len(indent) :] if ln.startswith(indent) else ln for ln in lines[i + 1 : end]]
            previous = next((lines[j] for j in range(i - 1, -1, -1) if lines[j].strip()), "")
            skip = _NOT_RUN.match(previous)
            reason = skip.group("reason") if skip else None
            if skip and not reason:
                raise SnippetError(f"{path}:{i}: a not-run snippet needs a reason")
            found.append(Snippet(path, i + 1, RUNNABLE[lang], "\n".join(body) + "\n", reason))
        i = end + 1
    return found


@contextlib.contextmanager
def _cwd(path: Path) -> Iterator[None]:
    old = Path.cwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def _run_bash(snippet: Snippet, workdir: Path) -> str:
    """Run a bash snippet in ``workdir``; its stdout."""
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env.setdefault("MPLBACKEND", "Agg")
    done = subprocess.run(
        ["bash", "-euo", "pipefail", "-c", snippet.code],
        cwd=workdir,
        env=env,
        capture_output=True,
        text=True,
        timeout=BASH_TIMEOUT_S,
        check=False,
    )
    if done.returncode != 0:
        tail = (done.stdout + done.stderr)[-3000:]
        raise SnippetError(f"{snippet.where}: bash exited {done.returncode}\n{tail}")
    return done.stdout


#: called before and after each snippet runs: ``(snippet, None)`` before, ``(snippet, its
#: stdout)`` after (a Python snippet's is ``""``), to check what the page's commands did
Watch = Callable[[Snippet, "str | None"], None]


def run_page(path: Path, workdir: Path, watch: Watch | None = None) -> list[Snippet]:
    """Run every runnable snippet of ``path`` in ``workdir``; return those that ran."""
    # a real module, so that classes a snippet defines (dataclasses) find their module
    module = types.ModuleType("__snippet__")
    sys.modules[module.__name__] = module
    try:
        return _run_all(snippets(path), workdir, module.__dict__, watch)
    finally:
        del sys.modules[module.__name__]


def _run_all(
    found: list[Snippet],
    workdir: Path,
    namespace: dict[str, object],
    watch: Watch | None = None,
) -> list[Snippet]:
    ran = []
    for snippet in found:
        if snippet.not_run is not None:
            continue
        if watch is not None:
            watch(snippet, None)
        stdout = ""
        if snippet.lang == "bash":
            stdout = _run_bash(snippet, workdir)
        else:
            code = compile(snippet.code, snippet.where, "exec")
            # numpy's default error handling, as a user has it (the suite's is stricter)
            with _cwd(workdir), np.errstate(all="warn", under="ignore"):
                try:
                    exec(code, namespace)
                except Exception as exc:
                    raise SnippetError(f"{snippet.where}: {type(exc).__name__}: {exc}") from exc
        if watch is not None:
            watch(snippet, stdout)
        ran.append(snippet)
    return ran
