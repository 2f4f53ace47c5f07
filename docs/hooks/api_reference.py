"""MkDocs hook: the API reference pages (``api/PACKAGE.md``), one per layer.

Each page holds the package's docstring and then every public module below it (names that do
not start with ``_``), rendered by mkdocstrings from the docstrings. The module list is read
from the source tree when the site is built, so a new module appears with no manual edit.

The layers' folders install as ``canonid.<folder>`` (``package-dir`` in pyproject.toml), a
mapping mkdocstrings' static loader does not follow; :func:`source_tree` lays the installed
shape out as symbolic links under ``build/docs-src`` (the ``paths`` of mkdocs.yml's handler).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
#: where the installed layout is laid out as links for mkdocstrings (git-ignored)
SOURCE_TREE = ROOT / "build" / "docs-src"
#: the layers' folders, from the root of the dependency graph up (the application -> {datagen,
#: learning, analysis} -> models -> kernel)
PACKAGES = ("kernel", "models", "datagen", "learning", "analysis", "canonid")


def dotted(package: str) -> str:
    """The installed name of a layer's folder (``learning`` → ``canonid.learning``)."""
    return "canonid" if package == "canonid" else f"canonid.{package}"


def public_modules(package: str, root: Path = ROOT) -> list[str]:
    """Dotted names of the public modules of folder ``package`` (sub-packages included), sorted."""
    base = root / package
    names = []
    for path in sorted(base.rglob("*.py")):
        parts = path.relative_to(base).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if any(p.startswith("_") for p in parts):
            continue
        names.append(".".join((dotted(package), *parts)))
    return sorted(set(names) - {dotted(package)})


def render(package: str, root: Path = ROOT) -> str:
    name = dotted(package)
    lines = [f"# `{name}`", "", f"::: {name}", "    options:"]
    lines += ["      show_root_heading: false", "      members: false", ""]
    for module in public_modules(package, root):
        lines += [f"::: {module}", "    options:", "      heading_level: 2", ""]
    return "\n".join(lines)


def _link(link: Path, target: Path) -> None:
    """``link`` → ``target``, replacing a stale link; safe when two builds race."""
    if link.is_symlink() and Path(os.readlink(link)) == target:
        return
    if link.is_symlink():
        link.unlink(missing_ok=True)
    try:
        link.symlink_to(target, target_is_directory=target.is_dir())
    except FileExistsError:
        pass


def source_tree(root: Path = ROOT, tree: Path = SOURCE_TREE) -> Path:
    """``tree/canonid`` shaped like the installed package: links to the application layer's
    files and to each layer's folder. Returns ``tree``."""
    package = tree / "canonid"
    package.mkdir(parents=True, exist_ok=True)
    wanted = {p.name: p for p in (root / "canonid").iterdir() if p.name != "__pycache__"}
    wanted |= {folder: root / folder for folder in PACKAGES if folder != "canonid"}
    for entry in package.iterdir():
        if entry.name not in wanted:
            entry.unlink(missing_ok=True)
    for name, target in wanted.items():
        _link(package / name, target)
    return tree


def on_startup(command: str, dirty: bool) -> None:
    """Lay out the installed shape before mkdocstrings reads its ``paths`` (``on_startup``
    event, before any plugin's ``on_config``)."""
    source_tree()


def on_files(files: Any, config: Any) -> Any:
    """Add one generated page per package (MkDocs ``on_files`` event)."""
    from mkdocs.structure.files import File

    for package in PACKAGES:
        files.append(File.generated(config, f"api/{package}.md", content=render(package)))
    return files
