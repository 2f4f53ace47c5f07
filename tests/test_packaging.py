"""What a packager meets: the package list of pyproject.toml, the version in one place, and a
wheel that installs non-editable and runs from a user's project folder.

The layers keep their folders at the top of the repository and install under ``canonid`` through
setuptools' ``package-dir``; a sub-package missing from ``packages`` would silently drop from the
wheel, and the editable install (whose finder maps the names at import time) would hide it. The
wheel test builds the wheel from a copy of the tree, installs it into a fresh venv that sees this
venv's dependencies (torch, CasADi, …) through a ``.pth`` line but not its editable ``canonid``,
and runs the command line from a folder holding a ``models.py`` or a ``models/`` package, where
the wheels of 0.1.0 before the single namespace failed with ``ModuleNotFoundError: No module
named 'models.lazy'``.
"""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest
import yaml

import canonid

if sys.version_info >= (3, 11):
    import tomllib
else:  # pytest depends on tomli before 3.11
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
SETUPTOOLS = PYPROJECT["tool"]["setuptools"]
#: installed package name → its folder in the repository
PACKAGE_DIR: dict[str, str] = SETUPTOOLS["package-dir"]
#: the files a wheel is built from besides the package folders
BUILD_FILES = ("pyproject.toml", "README.md", "LICENSE")


def _folder_of(package: str) -> Path:
    """The folder setuptools builds ``package`` from: the longest ``package-dir`` prefix, then
    the rest of the dotted name as sub-folders."""
    parts = package.split(".")
    for n in range(len(parts), 0, -1):
        prefix = ".".join(parts[:n])
        if prefix in PACKAGE_DIR:
            return ROOT / PACKAGE_DIR[prefix] / Path(*parts[n:])
    return ROOT / Path(*parts)


def _package_folders() -> dict[str, Path]:
    """Installed name → folder, of every folder with an ``__init__.py`` under a mapped folder."""
    found = {}
    for name, folder in PACKAGE_DIR.items():
        for init in sorted((ROOT / folder).rglob("__init__.py")):
            rest = init.parent.relative_to(ROOT / folder).parts
            found[".".join((name, *rest))] = init.parent
    return found


def test_every_top_level_package_folder_is_mapped_into_canonid():
    top = {p.parent.name for p in ROOT.glob("*/__init__.py")}
    assert top == set(PACKAGE_DIR.values())
    assert all(name == "canonid" or name.startswith("canonid.") for name in PACKAGE_DIR)
    assert set(PACKAGE_DIR.values()) == {
        "canonid",
        "kernel",
        "models",
        "datagen",
        "learning",
        "analysis",
    }


def test_every_package_folder_is_listed_and_every_listed_package_is_a_folder():
    folders = _package_folders()
    assert sorted(SETUPTOOLS["packages"]) == sorted(folders)
    for package in SETUPTOOLS["packages"]:
        assert _folder_of(package) == folders[package], package


def test_no_module_sits_in_a_folder_without_an_init():
    """A folder of modules without ``__init__.py`` is no package: the wheel would leave it out."""
    bare = [
        str(path.parent.relative_to(ROOT))
        for folder in PACKAGE_DIR.values()
        for path in (ROOT / folder).rglob("*.py")
        if "__pycache__" not in path.parts and not (path.parent / "__init__.py").exists()
    ]
    assert not bare, sorted(set(bare))


def test_the_version_is_stated_once():
    """``canonid.__version__`` is the source: pyproject reads it, CITATION.cff repeats it (and
    is checked here), and no other file names another version of canonid."""
    assert "version" not in PYPROJECT["project"] and "version" in PYPROJECT["project"]["dynamic"]
    assert SETUPTOOLS["dynamic"]["version"] == {"attr": "canonid.__version__"}
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert citation["version"] == canonid.__version__
    assigned = [
        str(path.relative_to(ROOT))
        for folder in PACKAGE_DIR.values()
        for path in (ROOT / folder).rglob("*.py")
        if any(
            isinstance(node, ast.Assign)
            and any(getattr(t, "id", None) == "__version__" for t in node.targets)
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        )
    ]
    assert assigned == ["canonid/__init__.py"]
    stated = re.compile(r"canonid(?:==| v?)(\d+\.\d+(?:\.\d+)?)\b", re.IGNORECASE)
    texts = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").glob("*.md"))]
    others = {
        (path.name, version)
        for path in texts
        for version in stated.findall(path.read_text(encoding="utf-8"))
        if version != canonid.__version__
    }
    assert not others, others


def test_citation_file_holds_the_fields_cff_requires():
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert citation["cff-version"] == "1.2.0"
    for field in ("message", "title", "authors", "license", "abstract"):
        assert citation[field], field
    assert citation["license"] == PYPROJECT["project"]["license"] == "MIT"
    assert "MIT License" in (ROOT / "LICENSE").read_text(encoding="utf-8")


# -- the wheel, installed non-editable ---------------------------------------------------------


def _run(argv, *, cwd, env, timeout=600) -> subprocess.CompletedProcess:
    res = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, f"{argv}\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
    return res


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A wheel built from a copy of the tree (nothing written into the checkout), installed with
    ``--no-deps`` into a fresh venv; then a ``.pth`` file lists this venv's site-packages, so the
    fresh venv finds the dependencies. ``site`` adds the folders a ``.pth`` names to
    ``sys.path`` without running the ``.pth`` files inside them, so the editable install's
    finder (``__editable__.canonid-*.pth``) stays off. Returns (python, bin folder,
    site-packages, wheel, env)."""
    tmp = tmp_path_factory.mktemp("wheel")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    src = tmp / "src"
    src.mkdir()
    for name in BUILD_FILES:
        shutil.copy2(ROOT / name, src / name)
    for folder in PACKAGE_DIR.values():
        shutil.copytree(ROOT / folder, src / folder, ignore=shutil.ignore_patterns("__pycache__"))
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check"]
    build = [
        *pip,
        "wheel",
        "--no-deps",
        "--no-build-isolation",
        "--no-index",
        "-w",
        "dist",
        "./src",
    ]
    _run(build, cwd=tmp, env=env)
    (wheel,) = (tmp / "dist").glob("canonid-*.whl")

    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)], cwd=tmp, env=env)
    python = venv / "bin" / "python"
    _run(
        [*pip, "--python", str(python), "install", "--no-deps", "--no-index", str(wheel)],
        cwd=tmp,
        env=env,
    )
    code = "import sysconfig; print(sysconfig.get_path('purelib'))"
    site_packages = Path(_run([str(python), "-c", code], cwd=tmp, env=env).stdout.strip())
    ours = dict.fromkeys([sysconfig.get_path("purelib"), sysconfig.get_path("platlib")])
    (site_packages / "test-venv-dependencies.pth").write_text("".join(f"{p}\n" for p in ours))
    return python, venv / "bin", site_packages, wheel, env


def test_the_wheel_installs_one_top_level_name_and_every_module(installed):
    *_, wheel, _ = installed
    names = zipfile.ZipFile(wheel).namelist()
    version = canonid.__version__
    assert wheel.name == f"canonid-{version}-py3-none-any.whl"
    assert {n.split("/")[0] for n in names} == {"canonid", f"canonid-{version}.dist-info"}
    assert f"canonid-{version}.dist-info/licenses/LICENSE" in names
    expected = {
        "/".join((*name.split("."), path.name))
        for name, folder in _package_folders().items()
        for path in folder.glob("*.py")
    }
    assert expected <= set(names), sorted(expected - set(names))


def _project(tmp: Path, shape: str) -> Path:
    """A user's project folder whose ``models`` (and the other layers' folder names) is their own:
    a module or a package that fails loudly if canonid imports it."""
    tmp.mkdir()
    for name in ("models", "datagen", "learning", "analysis", "kernel"):
        body = f"raise ImportError('the project\\'s own {name} was imported')\n"
        if shape == "module":
            (tmp / f"{name}.py").write_text(body)
        else:
            (tmp / name).mkdir()
            (tmp / name / "__init__.py").write_text(body)
    return tmp


def _write_csv(path: Path) -> None:
    """Four experiments of a first-order lag y[t+1] = 0.9 y[t] + 0.1 u[t] under input steps."""
    rows = ["run,pump,level"]
    for run in range(4):
        y = 0.0
        for t in range(60):
            u = 1.0 + ((3 * run + t // 10) % 4) * 0.5
            rows.append(f"r{run},{u!r},{y!r}")
            y = 0.9 * y + 0.1 * u
    path.write_text("\n".join(rows) + "\n")


@pytest.mark.slow
@pytest.mark.parametrize("shape", ["module", "package"])
def test_the_installed_wheel_runs_from_a_folder_with_its_own_models(installed, tmp_path, shape):
    python, bin_dir, site_packages, _, env = installed
    project = _project(tmp_path / "project", shape)
    # the project folder is sys.path[0] of `python -m` and `-c`: where the old wheel broke
    where = _run(
        [
            str(python),
            "-c",
            "import sys, importlib\n"
            "for m in ('canonid', 'canonid.kernel', 'canonid.models', 'canonid.datagen',\n"
            "          'canonid.learning', 'canonid.analysis', 'canonid.cli', 'torch'):\n"
            "    print(importlib.import_module(m).__file__)\n"
            "print(any('editable' in repr(f).lower() for f in sys.meta_path + sys.path_hooks))\n"
            "print(sorted(m for m in sys.modules if 'editable' in m.lower()))\n",
        ],
        cwd=project,
        env=env,
    ).stdout.splitlines()
    *ours, torch_file, finder_on, finder_modules = where
    assert all(Path(f).is_relative_to(site_packages / "canonid") for f in ours), ours
    assert not Path(torch_file).is_relative_to(site_packages), torch_file  # the test venv's
    assert finder_on == "False" and finder_modules == "[]"

    out = _run([str(bin_dir / "canonid"), "--help"], cwd=project, env=env).stdout
    assert "usage: canonid" in out
    version = _run([str(bin_dir / "canonid"), "--version"], cwd=project, env=env).stdout
    assert version.split() == ["canonid", canonid.__version__]
    for launcher in ([str(bin_dir / "canonid")], [str(python), "-m", "canonid"]):
        assert "tank:" in _run([*launcher, "systems"], cwd=project, env=env).stdout

    _write_csv(project / "data.csv")
    train = [str(python), "-m", "canonid", "train", "data.csv", "--inputs", "pump"]
    train += ["--outputs", "level", "--dt", "1", "--experiment-column", "run", "--model", "mlp"]
    train += ["--window", "2", "--hidden", "8,8", "--profile", "tiny", "--epochs", "3"]
    train += ["--device", "cpu", "--threads", "1", "--no-progress", "--out", "runs/csv"]
    _run(train, cwd=project, env={**env, "OMP_NUM_THREADS": "1"})
    history = (project / "runs" / "csv" / "history.csv").read_text().splitlines()
    assert [row.split(",")[0] for row in history[1:]] == ["0", "1", "2", "3"]  # 0: before training
    assert (project / "runs" / "csv" / "checkpoint.pt").is_file()
