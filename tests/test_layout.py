"""The dependency direction, checked statically and at import time.

Everything installs under one name, ``canonid``; each layer keeps its folder at the top of the
repository (``kernel/`` is ``canonid.kernel``, ``models/`` is ``canonid.models``, …, and
``canonid/`` is the application layer). Imports point one way: the application → {datagen,
learning, analysis} → models → kernel; the three middle layers do not import each other;
``analysis`` and ``models`` never import torch; ``learning`` never imports CasADi; the kernel
imports none of CasADi, torch or scipy. Inside the application the command line is the top floor:
only ``canonid.cli`` and the commands import ``canonid.commands``. No module imports a private
name of another layer, no module names a folder as a top-level package (only ``canonid`` is
installed), and no modules import each other (counting imports inside functions and those for
type checkers only). Importing a package costs nothing until a name of it is used, and reading
data (a CSV file, a canonid dataset) loads neither CasADi, torch nor matplotlib.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from canonid.commands import command_names

ROOT = Path(__file__).resolve().parents[1]
#: folder → the layer's installed name
LAYERS = {
    "kernel": "canonid.kernel",
    "models": "canonid.models",
    "datagen": "canonid.datagen",
    "learning": "canonid.learning",
    "analysis": "canonid.analysis",
    "canonid": "canonid",
}
PACKAGES = tuple(LAYERS)

#: what each layer must not import: other layers (by folder) and third-party roots
FORBIDDEN = {
    "kernel": {"models", "datagen", "learning", "analysis", "canonid", "torch", "casadi", "scipy"},
    "models": {"datagen", "learning", "analysis", "canonid", "torch"},
    "datagen": {"learning", "analysis", "canonid", "torch"},
    "learning": {"datagen", "analysis", "canonid", "casadi"},
    "analysis": {"datagen", "learning", "canonid", "torch"},
    "canonid": set(),
}


def _module(path: Path) -> str:
    folder, *rest = path.relative_to(ROOT).with_suffix("").parts
    return ".".join((LAYERS[folder], *rest)).removesuffix(".__init__")


def layer_of(module: str) -> str:
    """The folder of a ``canonid`` module (``canonid.learning.nets`` → ``learning``), or the
    third-party root of any other (``torch.nn`` → ``torch``)."""
    if module == "canonid" or module.startswith("canonid."):
        parts = module.split(".")
        if len(parts) > 1 and f"canonid.{parts[1]}" in LAYERS.values() and parts[1] in LAYERS:
            return parts[1]
        return "canonid"
    return module.split(".")[0]


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
    """The project modules ``module`` imports (a ``from package import module`` counts), for
    type checkers too: two modules that name each other's types still need each other."""
    return {m for m in _imported_modules(MODULES[module]) if m in MODULES} - {module}


def _imported_modules(path: Path) -> set[str]:
    """Every absolute import of ``path``, for type checkers too (``from a import b`` gives
    ``a`` and ``a.b``: ``b`` may be a module)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return found


def _imported_layers(path: Path) -> set[str]:
    return {layer_of(m) for m in _imported_modules(path)}


@pytest.mark.parametrize("package", PACKAGES)
def test_static_imports_point_one_way(package):
    offenders = []
    for path in sorted((ROOT / package).rglob("*.py")):
        bad = (_imported_layers(path) - {package}) & FORBIDDEN[package]
        if bad:
            offenders.append(f"{path.relative_to(ROOT)} imports {sorted(bad)}")
    assert not offenders, "\n".join(offenders)


def test_no_folder_is_imported_as_a_top_level_package():
    """Only ``canonid`` is installed: ``import models`` works from the repository root and
    nowhere else, so an import of a folder's name is a bug (and a second copy of the module)."""
    top = set(LAYERS) - {"canonid"}
    offenders = [
        f"{path.relative_to(ROOT)} imports {m}"
        for path in [
            *MODULES.values(),
            *sorted((ROOT / "tests").glob("*.py")),
            *sorted((ROOT / "benchmarks").rglob("*.py")),
            *sorted((ROOT / "docs" / "hooks").glob("*.py")),
        ]
        for m in sorted(_imported_modules(path))
        if m.split(".")[0] in top
    ]
    assert not offenders, "\n".join(offenders)


@pytest.mark.parametrize(
    ("package", "blocked"),
    [
        ("kernel", "torch"),
        ("kernel", "casadi"),
        ("kernel", "scipy"),
        ("models", "torch"),
        ("analysis", "torch"),
        ("datagen", "torch"),
        ("learning", "casadi"),
    ],
)
def test_package_imports_without(package, blocked):
    """Import every module of ``package`` in a fresh interpreter where ``blocked`` cannot load."""
    modules = sorted(m for m, p in MODULES.items() if p.is_relative_to(ROOT / package))
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


def _heavy_after(code: str) -> set[str]:
    """The heavy packages a fresh interpreter holds after running ``code``."""
    probe = (
        f"{code}\n"
        "import sys\n"
        "heavy = ('numpy', 'scipy', 'casadi', 'torch', 'matplotlib')\n"
        "print(' '.join(m for m in heavy if m in sys.modules))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr[-2000:]
    return set(res.stdout.split())


def test_importing_a_package_loads_nothing_heavy():
    """Every package ``__init__`` exports its names lazily (:mod:`canonid.kernel.lazy`)."""
    code = "\n".join(f"import {name}" for name in LAYERS.values())
    assert _heavy_after(code) == set()


def test_a_lazy_export_is_the_name_whatever_was_imported_first():
    """Importing the module that defines an export binds the module on the package; the export
    (``canonid.learning.evaluate``, the function of ``canonid.learning.evaluate``) still wins."""
    code = (
        "import importlib\n"
        f"for package in {sorted(LAYERS.values())!r}:\n"
        "    p = importlib.import_module(package)\n"
        "    exports = getattr(p, '_EXPORTS', {})\n"
        "    homes = {n: importlib.import_module(m) for n, m in exports.items()}\n"
        "    for name, home in homes.items():\n"
        "        assert getattr(p, name) is getattr(home, name), (package, name)\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr[-2000:]


def test_loading_data_imports_no_casadi_torch_or_matplotlib(tmp_path):
    """A CSV file and a canonid dataset read through ``canonid.load_data`` need numpy only."""
    from canonid.kernel.dataset import Dataset

    rows = "".join(f"{0.1 * t},{t % 3},{t % 5}\n" for t in range(20))
    (tmp_path / "run.csv").write_text("time,u,y\n" + rows, encoding="utf-8")
    Dataset.from_arrays(np.arange(12.0), np.ones(12), dt=0.5).save(tmp_path / "ds" / "dataset.npz")
    code = (
        "import canonid\n"
        f"csv = canonid.load_data({str(tmp_path / 'run.csv')!r}, inputs=['u'], outputs=['y'],"
        " dt=0.1)\n"
        "assert [tr.T for tr in csv.split('train')] == [20]\n"
        f"ds = canonid.load_data({str(tmp_path / 'ds')!r})\n"
        "assert ds.dt == 0.5 and ds.split('train')[0].T == 12\n"
    )
    assert _heavy_after(code) == {"numpy"}


def test_layout_is_the_design_card():
    for entry in (
        "pyproject.toml",
        "kernel",
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
        if layer_of(module) == "canonid"
        and module != "canonid.cli"
        and not module.startswith("canonid.commands")
        and any(target.startswith("canonid.commands") for target, _ in _imports(path))
    ]
    assert not offenders, offenders


#: what the commands may import, by name: the standard library's argument and text helpers, the
#: commands' own helpers, the kernel's plain names (errors, the catalog, the figure formats), and
#: the application modules they call (never a library layer — canonid.learning, datagen,
#: analysis, models — nor another kernel module directly)
COMMAND_IMPORTS = {
    "__future__",
    "argparse",
    "difflib",
    "importlib",
    "logging",
    "os",
    "sys",
    "collections.abc",
    "dataclasses",
    "pathlib",
    "types",
    "typing",
}
COMMAND_KERNEL = {"canonid.kernel.catalog", "canonid.kernel.errors", "canonid.kernel.io"}
COMMAND_APPLICATION = {
    "canonid",
    "canonid.benchmark",
    "canonid.data_options",
    "canonid.generation",
    "canonid.jobs",
    "canonid.learned",
    "canonid.profiles",
    "canonid.reduction",
    "canonid.reproduce",
    "canonid.residual_check",
    "canonid.scoring",
    "canonid.systems",
    "canonid.theory",
    "canonid.training",
}
#: the most lines ``commands/`` may hold: a command parses, calls the application and prints
#: (1,050 before the one grammar's shared options: the deprecated bare form of an option;
#: 1,075 before train's help sections, the one list syntax and benchmark taking train's options)
COMMAND_LINES = 1_200


def _command_modules() -> dict[str, Path]:
    return {
        m: p for m, p in MODULES.items() if m.startswith("canonid.commands") or m == "canonid.cli"
    }


def test_the_commands_import_only_the_application_and_the_kernel():
    offenders = [
        f"{module} imports {target}"
        for module, path in _command_modules().items()
        for target, _ in _imports(path)
        if target not in COMMAND_IMPORTS | COMMAND_KERNEL | COMMAND_APPLICATION
        and not target.startswith("canonid.commands")
    ]
    assert not offenders, offenders


def test_a_command_module_registers_and_runs_only():
    """A subcommand's module defines ``register`` and ``run`` (``train`` also ``request``, which
    ``benchmark`` reads ``--train-args`` with) and private argparse helpers; the rules and the
    printing live in the application."""
    allowed = {"register", "run", "request", "train_request"}
    offenders = [
        f"{module}.{node.name}"
        for module, path in _command_modules().items()
        if module.split(".")[-1] in command_names()
        for node in ast.parse(path.read_text(encoding="utf-8")).body
        if isinstance(node, ast.FunctionDef | ast.ClassDef)
        and not node.name.startswith("_")
        and node.name not in allowed
    ]
    assert not offenders, offenders


def test_the_commands_stay_thin():
    files = sorted((ROOT / "canonid" / "commands").glob("*.py"))
    lines = sum(len(p.read_text(encoding="utf-8").splitlines()) for p in files)
    assert lines <= COMMAND_LINES, f"canonid/commands/ holds {lines} lines"


@pytest.mark.parametrize("command", [None, *command_names()])
def test_help_imports_neither_torch_nor_casadi(command):
    """``canonid [COMMAND] --help`` builds the parser only: no torch, CasADi, scipy or
    matplotlib (generate lists its scenarios, benchmark its benchmarks, without them)."""
    argv = ["--help"] if command is None else [command, "--help"]
    code = (
        "import sys\n"
        "from canonid.cli import main\n"
        "try:\n"
        f"    main({argv!r})\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted({'torch', 'casadi', 'scipy', 'matplotlib'} & set(sys.modules)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    ).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_no_private_name_of_another_package_is_imported():
    offenders = [
        f"{module} imports {target}.{name}"
        for module, path in MODULES.items()
        for target, names in _imports(path)
        for name in names
        if name.startswith("_") and layer_of(target) != layer_of(module)
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


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_cycle(package):
    """Within each layer (across layers the one-way rule above excludes cycles)."""
    modules = [m for m in MODULES if layer_of(m) == package]
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
    assert defined == ["canonid.kernel.io"]


def test_one_job_abstraction():
    """Inside ``canonid`` a job's torch threads are set and restored in ``canonid.jobs`` only
    (a command's ``--threads`` sets them for its process), and ``result.json`` is read and
    written there only."""
    offenders = [
        module
        for module, path in MODULES.items()
        if layer_of(module) == "canonid"
        and not module.startswith(("canonid.commands", "canonid.jobs"))
        and "set_num_threads" in path.read_text(encoding="utf-8")
    ]
    assert not offenders, offenders
    writers = [
        module
        for module, path in MODULES.items()
        if layer_of(module) == "canonid"
        and module != "canonid.jobs"
        and 'RESULT_FILE = "' in path.read_text(encoding="utf-8")
    ]
    assert not writers, writers


def test_the_catalog_names_what_the_networks_know():
    """The plain-data names in canonid.kernel.catalog (what --help shows without torch) are
    the registry's models, the MLPs' activations and the affine paths, in that order."""
    from canonid.kernel import catalog
    from canonid.learning import model_names
    from canonid.learning.nets.base import ACTIVATIONS, LINEAR_PATHS

    assert catalog.MODEL_NAMES == tuple(model_names())
    assert catalog.ACTIVATION_NAMES == tuple(sorted(ACTIVATIONS))
    assert catalog.LINEAR_PATHS == LINEAR_PATHS
