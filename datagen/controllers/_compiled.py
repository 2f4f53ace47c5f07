"""Turn CasADi ``Function``s (e.g. a fatrop ``nlpsol`` and loops around it) into compiled C,
cached on disk.

The functions go into one C file (shared parts such as the solver are generated once). The C
source CasADi generates for them is hashed together with the compiler command
and the CasADi version; the shared library lives at ``<cache_dir>/<name>-<hash>.so`` and is
built on first use only (in a temporary file renamed into place, so concurrent workers that
build the same library at once are harmless). Beside it, ``<name>-<hash>.so.sha256`` holds the
SHA-256 of the library's bytes: a cached library that does not match it (truncated, damaged,
replaced) or lacks it is rebuilt rather than loaded, since loading a damaged shared library can
kill the process without a message (SIGBUS). The default cache folder is
``$CANONID_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/canonid`` (``~/.cache/canonid``), never
the working directory. When no C compiler is found or the build fails, :func:`compile_functions`
returns ``None`` and the caller keeps the pure-CasADi functions.

The compiler runs with ``-ffp-contract=off``: no fused multiply-adds, so the compiled functions
round exactly as CasADi's own evaluation of the same expressions (bit-identical results).
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

from canonid.kernel.io import atomic_write_text, sha256_file

__all__ = ["compile_functions", "default_cache_dir"]

log = logging.getLogger(__name__)

_CASADI_DIR = Path(ca.__file__).resolve().parent


def default_cache_dir() -> Path:
    """``$CANONID_CACHE_DIR``, else ``$XDG_CACHE_HOME/canonid``, else ``~/.cache/canonid``."""
    explicit = os.environ.get("CANONID_CACHE_DIR")
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base).expanduser() / "canonid"


def compile_functions(
    functions: Sequence[ca.Function],
    *,
    name: str,
    cache_dir: str | os.PathLike[str] | None = None,
    libraries: tuple[str, ...] = (),
    compiler: str = "gcc",
    flags: tuple[str, ...] = ("-O2", "-ffp-contract=off"),
) -> tuple[ca.Function, ...] | None:
    """``functions`` generated to one C file, compiled and loaded with ``ca.external`` (in the
    same order); ``None`` when no compiler is available or the build fails (logged as a
    warning).

    Args:
        functions: the functions to generate (names distinct; inputs and outputs are kept).
        name: file-name prefix of the cached library.
        cache_dir: where libraries are kept (default :func:`default_cache_dir`).
        libraries: shared libraries of the CasADi wheel to link (e.g. ``("fatrop", "blasfeo")``);
            they are found, and found again at run time, in the wheel's own folder.
        compiler, flags: the C compiler and its optimisation flags.
    """
    exe = shutil.which(compiler)
    if exe is None:
        log.warning("no C compiler %r found: using the pure-CasADi solver", compiler)
        return None
    generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    for function in functions:
        generator.add(function)
    source = generator.dump()
    compile_args = [exe, *flags, "-fPIC", "-shared", f"-I{_CASADI_DIR / 'include'}"]
    # libraries after the source: linkers that drop unneeded libraries read left to right
    link_args = [
        f"-L{_CASADI_DIR}",
        *(f"-l{lib}" for lib in libraries),
        f"-Wl,-rpath,{_CASADI_DIR}",
    ]
    digest = hashlib.sha256(
        "\0".join([source, *compile_args, *link_args, ca.CasadiMeta.version()]).encode("utf-8")
    ).hexdigest()[:20]
    folder = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    library = folder / f"{name}-{digest}.so"
    if not _verified(library):
        try:
            _build(source, compile_args, link_args, folder, library)
        except (OSError, subprocess.CalledProcessError) as exc:
            detail = getattr(exc, "stderr", "") or exc
            log.warning("building %s failed, using the pure-CasADi solver: %s", library, detail)
            return None
    try:
        return tuple(ca.external(function.name(), str(library)) for function in functions)
    except RuntimeError as exc:
        log.warning("loading %s failed, using the pure-CasADi solver: %s", library, exc)
        return None


def _checksum_file(library: Path) -> Path:
    return library.with_name(library.name + ".sha256")


def _verified(library: Path) -> bool:
    """Whether ``library`` exists and matches the checksum written when it was built."""
    if not library.exists():
        return False
    try:
        expected = _checksum_file(library).read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        expected = ""
    if expected and expected == sha256_file(library):
        return True
    log.warning("cached library %s does not match its checksum: rebuilding it", library)
    return False


def _build(
    source: str, compile_args: list[str], link_args: list[str], folder: Path, library: Path
) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder, prefix=".build-") as tmp:
        c_file = Path(tmp) / "solver.c"
        c_file.write_text(source, encoding="utf-8")
        target = Path(tmp) / library.name
        subprocess.run(
            [*compile_args, str(c_file), "-o", str(target), *link_args],
            check=True,
            capture_output=True,
            text=True,
        )
        checksum = sha256_file(target)
        os.replace(target, library)
    atomic_write_text(_checksum_file(library), checksum + "\n")
    log.info("compiled %s", library)
