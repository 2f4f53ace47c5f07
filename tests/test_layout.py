"""The dependency direction, checked statically and at import time.

canonid → {datagen, learning, analysis} → models; the three middle layers do not import each
other; ``analysis`` and ``models`` never import torch; ``learning`` never imports CasADi. Inside
``canonid`` the command line is the top floor: only ``canonid.cli`` and the commands import
``canonid.commands``. No module imports a private name of another package, and no modules
import each other (counting imports inside functions, not those for type checkers only).
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


def _module(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


MODULES = {_module(p): p for package in PACKAGES for p in sorted((ROOT / package).rglob("*.py"))}


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """``(module, names)`` of every absolute import in ``path``, inside functions too, except
    those under ``if TYPE_CHECKING:`` (``import a.b`` gives ``("a.b", [])``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    typing_only = {
        id(inner)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
        for inner in ast.walk(node)
    }
    found: list[tuple[str, list[str]]] = []
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            found.extend((alias.name, []) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.module, [alias.name for alias in node.names]))
    return found


def _dependencies(module: str) -> set[str]:
    """The project modules ``module`` imports (a ``from package import module`` counts)."""
    deps = set()
    for target, names in _imports(MODULES[module]):
        deps.update(m for m in (target, *(f"{target}.{n}" for n in names)) if m in MODULES)
    return deps - {module}


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


def test_only_the_command_line_imports_the_commands():
    offenders = [
        module
        for module, path in MODULES.items()
        if module.startswith("canonid.")
        and module != "canonid.cli"
        and not module.startswith("canonid.commands")
        and any(target.startswith("canonid.commands") for target, _ in _imports(path))
    ]
    assert not offenders, offenders


def test_no_private_name_of_another_package_is_imported():
    offenders = [
        f"{module} imports {target}.{name}"
        for module, path in MODULES.items()
        for target, names in _imports(path)
        for name in names
        if name.startswith("_") and target.split(".")[0] != module.split(".")[0]
    ]
    assert not offenders, "\n".join(offenders)


def _cycles(modules: list[str]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(_dependencies(v) & set(modules)):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = stack[stack.index(v) :]
            del stack[stack.index(v) :]
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in modules:
        if v not in index:
            visit(v)
    return cycles


@pytest.mark.parametrize(
    "package",
    [
        "models",
        "datagen",
        "learning",
        "analysis",
        "canonid",
    ],
)
def test_no_import_cycle(package):
    """Within each package (across packages the one-way rule above excludes cycles)."""
    modules = [m for m in MODULES if m.split(".")[0] == package]
    assert _cycles(modules) == []


#: the original design contract's section marks (written in two parts so this file has none)
SPEC_MARK = "SPEC " + "§"


def test_code_and_tests_cite_no_document_outside_the_repository():
    files = [*MODULES.values(), *sorted((ROOT / "tests").glob("*.py"))]
    offenders = [
        str(path.relative_to(ROOT))
        for path in files
        if SPEC_MARK in path.read_text(encoding="utf-8")
    ]
    assert not offenders, offenders


def test_figures_use_the_object_api():
    """Library code draws on ``matplotlib.figure.Figure``: pyplot's global state and backend
    belong to the user's session."""
    offenders = [
        f"{module} imports {target}"
        for module, path in MODULES.items()
        for target, names in _imports(path)
        if target == "matplotlib.pyplot" or (target == "matplotlib" and "pyplot" in names)
    ]
    offenders += [m for m, p in MODULES.items() if "matplotlib.use(" in p.read_text("utf-8")]
    assert not offenders, offenders


def test_one_jsonable():
    defined = [
        module
        for module, path in MODULES.items()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.FunctionDef) and node.name.lstrip("_") == "jsonable"
    ]
    assert defined == ["models.io"]


def test_one_job_abstraction():
    """Inside ``canonid`` a job's torch threads are set and restored in ``canonid.jobs`` only
    (a command's ``--threads`` sets them for its process), and ``result.json`` is read and
    written there only."""
    offenders = [
        module
        for module, path in MODULES.items()
        if module.startswith("canonid.")
        and not module.startswith(("canonid.commands", "canonid.jobs"))
        and "set_num_threads" in path.read_text(encoding="utf-8")
    ]
    assert not offenders, offenders
    writers = [
        module
        for module, path in MODULES.items()
        if module.startswith("canonid.")
        and module != "canonid.jobs"
        and 'RESULT_FILE = "' in path.read_text(encoding="utf-8")
    ]
    assert not writers, writers
