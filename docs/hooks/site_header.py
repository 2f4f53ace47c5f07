"""MkDocs hook: the header names the version of canonid that built the site.

The version comes from ``canonid.__version__`` (the one place it is written), so the header can
never name another. When ``pyproject.toml`` gives the repository (``[project.urls]``, key
``Repository``), the header links to it; no address is written anywhere else.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def repository() -> str | None:
    """The repository address of ``pyproject.toml``'s ``[project.urls]``, if it gives one."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: no TOML reader in the standard library
        return None
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    return project.get("urls", {}).get("Repository")


def on_config(config: Any, **_: Any) -> Any:
    """Put the version beside the site's name (MkDocs ``on_config`` event)."""
    from canonid import __version__

    config["site_name"] = f"canonid {__version__}"
    url = repository()
    if url and not config.get("repo_url"):
        config["repo_url"] = url
        config["repo_name"] = f"canonid {__version__}"
    return config
