"""The documentation: README length and links, every snippet runs, the site builds strictly,
and the generated command-line page lists every flag of every parser."""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import math
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from doc_snippets import Snippet, SnippetError, run_page, snippets

from canonid.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(
    [ROOT / "README.md", *(p for p in DOCS.rglob("*.md") if "hooks" not in p.parts)],
    key=lambda p: str(p),
)


def _hook(name: str):
    spec = importlib.util.spec_from_file_location(name, DOCS / "hooks" / f"{name}.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _page_param(path: Path):
    # pages that run shell commands start canonid processes (seconds each): slow
    shell = any(s.lang == "bash" and s.not_run is None for s in snippets(path))
    marks = [pytest.mark.slow] if shell else []
    return pytest.param(path, id=str(path.relative_to(ROOT)), marks=marks)


def test_readme_is_short():
    n = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert n <= 100, f"README.md has {n} lines; the docs site is the place for more"


def test_readme_links_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if "://" not in t]
    assert local, "the README links to the docs"
    generated = {"docs/cli.md"}  # written by docs/hooks/cli_reference.py when the site builds
    missing = [t for t in local if t not in generated and not (ROOT / t).exists()]
    assert not missing, f"README.md links to missing files: {missing}"


class HeldOutKeepsTraining:
    """ "Your own data": training's ``metrics.json`` is the same bytes before and after the
    held-out evaluation, which is written into a folder of its own; checked after every
    snippet from the evaluation on."""

    def __init__(self, workdir: Path) -> None:
        self.metrics = workdir / "runs" / "csv-mlp" / "metrics.json"
        self.before: bytes | None = None
        self.evaluated = False

    def __call__(self, snippet: Snippet, stdout: str | None) -> None:
        evaluation = "canonid evaluate runs/csv-mlp --data held_out.csv" in snippet.code
        if evaluation and stdout is None:
            self.before = self.metrics.read_bytes()
        if self.before is not None and stdout is not None:
            assert self.metrics.read_bytes() == self.before, snippet.where
            if evaluation:
                self.evaluated = True
                assert (
                    "[all]" in stdout and "metrics written to runs/csv-mlp/evaluations/" in stdout
                )
                assert "held_out-" in stdout


class AnalyzeBracketsAreFinite:
    """The README's ``canonid analyze`` example prints finite certified brackets: γ_f ≤ a
    number, α_ℓ ≥ a positive number, a finite bound, and a finite error/bound ratio."""

    def __init__(self, workdir: Path) -> None:
        self.rows: list[list[float]] = []

    def __call__(self, snippet: Snippet, stdout: str | None) -> None:
        if stdout is None or "canonid analyze" not in snippet.code:
            return
        lines = stdout.splitlines()
        head = next(i for i, line in enumerate(lines) if line.split()[:2] == ["ℓ", "γ_f"])
        for line in lines[head + 2 :]:
            cells = line.split()
            if not cells or not cells[0].isdigit():
                break
            self.rows.append([float(c) for c in cells[1:8]])
        assert self.rows, stdout
        for gamma_lo, gamma_up, alpha_lo, alpha_up, bound, error, ratio in self.rows:
            assert all(math.isfinite(v) for v in (gamma_up, bound, ratio)), stdout
            assert 0 < gamma_lo <= gamma_up and 0 < alpha_lo <= alpha_up, stdout
            assert 0 < ratio <= 1 and error <= bound, stdout


#: what a page's commands must have done, beside running (a checker per page)
WATCHES = {"docs/your-data.md": HeldOutKeepsTraining, "README.md": AnalyzeBracketsAreFinite}


@pytest.mark.parametrize("page", [_page_param(p) for p in PAGES])
def test_snippets_run(page: Path, tmp_path: Path):
    make = WATCHES.get(str(page.relative_to(ROOT)))
    watch = make(tmp_path) if make else None
    run_page(page, tmp_path, watch)
    if isinstance(watch, HeldOutKeepsTraining):
        assert watch.evaluated, "the held-out evaluation ran"
    if isinstance(watch, AnalyzeBracketsAreFinite):
        assert watch.rows, "the analyze example ran"


def test_not_run_snippets_say_why():
    for page in PAGES:
        for snippet in snippets(page):
            assert snippet.not_run is None or len(snippet.not_run) > 10, snippet.where


def test_a_broken_snippet_fails(tmp_path: Path):
    page = tmp_path / "page.md"
    page.write_text(
        "<!-- snippet-setup: bash\necho 1.5 > x.txt\n-->\n"
        "```python\nvalue = float(open('x.txt').read())\n```\n"
        "<!-- snippet: not-run — would fail, and says why it is not run -->\n"
        "```bash\nexit 3\n```\n"
        "```python\nassert value == 2.0, 'value'\n```\n",
        encoding="utf-8",
    )
    with pytest.raises(SnippetError, match=r"page\.md:11: AssertionError: value"):
        run_page(page, tmp_path)
    page.write_text("text\n\n```bash\necho fine\nls no-such-file\necho never\n```\n")
    with pytest.raises(SnippetError, match=r"page\.md:3: bash exited 2"):
        run_page(page, tmp_path)


@pytest.mark.parametrize(
    ("markdown", "message"),
    [
        ("```\nls\n```\n", "without a language"),
        ("<!-- snippet: not-run — -->\n```bash\nls\n```\n", "needs a reason"),
        ("<!-- snippet: skip this -->\n```bash\nls\n```\n", "unreadable snippet marker"),
        ("```python\nx = 1\n", "never closed"),
    ],
)
def test_markup_errors_are_named(tmp_path: Path, markdown: str, message: str):
    page = tmp_path / "page.md"
    page.write_text(markdown, encoding="utf-8")
    with pytest.raises(SnippetError, match=message):
        snippets(page)


def _options(parser: argparse.ArgumentParser) -> list[str]:
    names = [
        o
        for a in parser._actions
        if a.help is not argparse.SUPPRESS  # a former name, still read, not documented
        for o in a.option_strings
        if o not in ("-h", "--help")
    ]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                names += _options(sub)
    return names


def test_cli_reference_lists_every_subcommand_and_flag():
    parser = build_parser(every=True)
    page = _hook("cli_reference").render(parser)
    subcommands = next(
        a.choices for a in parser._actions if isinstance(a, argparse._SubParsersAction)
    )
    for name, sub in subcommands.items():
        assert f"## canonid {name}\n" in page
        section = page.split(f"## canonid {name}\n")[1].split("\n## canonid ")[0]
        for option in _options(sub):
            assert f"`{option}" in section, f"{option} of canonid {name} missing"


def test_api_reference_covers_public_modules():
    api = _hook("api_reference")
    modules = api.public_modules("learning")
    assert "canonid.learning.training" in modules and "canonid.learning.nets.base" in modules
    assert not any(part.startswith("_") for m in modules for part in m.split("."))
    assert "::: canonid.learning.training" in api.render("learning")


def test_site_builds_strictly(tmp_path: Path):
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "index.html").exists()
    assert (tmp_path / "cli" / "index.html").exists()
    assert (tmp_path / "api" / "learning" / "index.html").exists()


def test_docstring_rest_habits_become_markdown():
    markdown = _hook("griffe_rest").markdown
    text = (
        "Uses :func:`fit` and ``x``, see :class:`~canonid.learning.Model`.\n\n"
        "Example::\n\n    y = 1\n\n"
        "Args:\n    X, U: boxes for x and u.\n    seed (int): a seed.\n\nNotes: a, b: not args.\n"
    )
    assert markdown(text) == (
        "Uses `fit` and `x`, see `canonid.learning.Model`.\n\n"
        "Example:\n\n    y = 1\n\n"
        "Args:\n    X: boxes for x and u.\n    U: boxes for x and u.\n    seed (int): a seed.\n\n"
        "Notes: a, b: not args."
    )
    assert markdown(markdown(text)) == markdown(text)


def _canonid_commands(code: str) -> list[list[str]]:
    """The argument lists of the `canonid ...` / `python -m canonid ...` lines of a shell block."""
    joined = re.sub(r"\\\n\s*", " ", code)
    commands = []
    for line in joined.splitlines():
        if not line.lstrip().startswith(("canonid ", "python -m canonid ")):
            continue
        words = shlex.split(line, comments=True)
        if words[:1] == ["canonid"]:
            commands.append(words[1:])
        elif words[:3] == ["python", "-m", "canonid"]:
            commands.append(words[3:])
    return commands


def test_every_canonid_command_in_the_docs_parses():
    """Also the blocks that are not run: a renamed or removed flag fails here, in seconds."""
    parser = build_parser(every=True)
    checked, bad = 0, []
    for page in PAGES:
        for snippet in snippets(page):
            if snippet.lang != "bash":
                continue
            for argv in _canonid_commands(snippet.code):
                checked += 1
                try:
                    with contextlib.redirect_stderr(io.StringIO()) as err:
                        parser.parse_args(argv)
                except SystemExit:
                    why = err.getvalue().strip().splitlines()[-1:]
                    bad.append(f"{snippet.where}: canonid {shlex.join(argv)}: {why}")
    assert checked > 20
    assert not bad, "\n".join(bad)
