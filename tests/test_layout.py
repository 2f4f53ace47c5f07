"""The dependency direction of SPEC §2, checked statically and at import time.

canonid → {datagen, learning, analysis} → models; the three middle layers do not import each
other; ``analysis`` and ``models`` never import torch; ``learning`` never imports CasADi.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("models", "datagen", "learning", "analysis", "canonid")

FORBIDDEN = {
    "models": {"datagen", "learning", "analysis", "canonid", "torch"},
    "datagen": {"learning", "analysis", "canonid", "torch"},
    "learning": {"datagen", "analysis", "canonid", "casadi"},
    "analysis": {"datagen", "learning", "canonid", "torch"},
    "canonid": set(),
}


def _imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    roots: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            roots.add(node.module.split(".")[0])
    return roots


@pytest.mark.parametrize("package", PACKAGES)
def test_static_imports_point_one_way(package):
    offenders = []
    for path in sorted((ROOT / package).rglob("*.py")):
        bad = _imported_roots(path) & FORBIDDEN[package]
        if bad:
            offenders.append(f"{path.relative_to(ROOT)} imports {sorted(bad)}")
    assert not offenders, "\n".join(offenders)


@pytest.mark.parametrize(
    ("package", "blocked"),
    [("models", "torch"), ("analysis", "torch"), ("datagen", "torch"), ("learning", "casadi")],
)
def test_package_imports_without(package, blocked):
    """Import every module of ``package`` in a fresh interpreter where ``blocked`` cannot load."""
    modules = sorted(
        ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        for p in (ROOT / package).rglob("*.py")
    )
    code = (
        "import importlib, sys\n"
        f"sys.modules[{blocked!r}] = None\n"
        f"for m in {modules!r}:\n"
        "    importlib.import_module(m)\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr[-2000:]


def test_layout_is_the_design_card():
    for entry in (
        "pyproject.toml",
        "models",
        "datagen",
        "learning",
        "analysis",
        "tests",
        "canonid",
        "benchmarks",
        "Makefile",
        ".ci/run",
        "README.md",
    ):
        assert (ROOT / entry).exists(), entry
