"""MkDocs hook: the API reference pages (``api/PACKAGE.md``), one per layer.

Each page holds the package's docstring and then every public module below it (names that do
not start with ``_``), rendered by mkdocstrings from the docstrings. The module list is read
from the source tree when the site is built, so a new module appears with no manual edit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
#: the layers, from the root of the dependency graph (canonid -> {datagen, learning, analysis}
#: -> models) up
PACKAGES = ("models", "datagen", "learning", "analysis", "canonid")


def public_modules(package: str, root: Path = ROOT) -> list[str]:
    """Dotted names of the public modules of ``package`` (sub-packages included), sorted."""
    base = root / package
    names = []
    for path in sorted(base.rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if len(parts) > 1 and any(p.startswith("_") for p in parts[1:]):
            continue
        names.append(".".join(parts))
    return sorted(set(names) - {package})


def render(package: str, root: Path = ROOT) -> str:
    lines = [f"# `{package}`", "", f"::: {package}", "    options:"]
    lines += ["      show_root_heading: false", "      members: false", ""]
    for module in public_modules(package, root):
        lines += [f"::: {module}", "    options:", "      heading_level: 2", ""]
    return "\n".join(lines)


def on_files(files: Any, config: Any) -> Any:
    """Add one generated page per package (MkDocs ``on_files`` event)."""
    from mkdocs.structure.files import File

    for package in PACKAGES:
        files.append(File.generated(config, f"api/{package}.md", content=render(package)))
    return files
