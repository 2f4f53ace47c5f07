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

Trust: loading a library runs its code inside this process, and a checksum beside it detects
damage, not tampering (whoever can replace the library can replace the checksum). So a library
is loaded only from a folder that no other user can change: the cache folder and every folder
above it must be owned by this user or root and writable by nobody else (a folder writable by
others is accepted above the cache only when it is sticky, as ``/tmp`` is: there nobody can
rename or delete another user's entries). A cache folder that fails this is not used at all,
with a warning naming the folder and the fix, and the caller keeps the pure-CasADi functions
(same results, slower): refusing the library must not make ``canonid generate`` unusable. In a
trusted folder, a library or checksum file that is not a regular file of this user (or root),
writable by nobody else, is rebuilt rather than loaded, with a warning. A new cache folder, and
any missing folder above it, is created ``0700``; libraries are written ``0755`` and checksums
``0644`` (less the umask).

The compiler runs with ``-ffp-contract=off``: no fused multiply-adds, so the compiled functions
round exactly as CasADi's own evaluation of the same expressions (bit-identical results).
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import stat
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
    try:
        _make_private(folder)
        # the real path from here on: a symlink re-pointed after the check changes nothing
        real = folder.resolve(strict=True)
        distrust = _untrusted_folder(real)
    except OSError as exc:
        log.warning("cannot use the cache folder %s, using the pure-CasADi solver: %s", folder, exc)
        return None
    if distrust:
        log.warning(
            "compiled-solver cache %s not used: %s, so another user could plant a library there "
            "that would run inside canonid; using the pure-CasADi solver (same results, slower). "
            "To use the cache, make every folder on its path yours and writable only by you "
            "(chmod go-w), or set CANONID_CACHE_DIR to a folder of your own",
            folder,
            distrust,
        )
        return None
    library = real / f"{name}-{digest}.so"
    if not _trusted_files(library) or not _verified(library):
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


def _untrusted(path: Path, *, parent: bool = False) -> str | None:
    """Why another user could change ``path`` (a file or folder, not followed if a symlink), or
    ``None``: it is owned by someone other than this user or root, or writable by group or
    others (for a ``parent``, unless it is sticky)."""
    info = path.lstat()
    if stat.S_ISLNK(info.st_mode):
        return f"{path} is a symbolic link"
    if info.st_uid not in (os.geteuid(), 0):
        return f"{path} is owned by uid {info.st_uid}, neither you (uid {os.geteuid()}) nor root"
    sticky = parent and stat.S_ISDIR(info.st_mode) and info.st_mode & stat.S_ISVTX
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH) and not sticky:
        return f"{path} is writable by others (mode {stat.S_IMODE(info.st_mode):04o})"
    return None


def _make_private(folder: Path) -> None:
    """Create ``folder`` and the folders above it that are missing, each ``0700``."""
    for missing in reversed([p for p in (folder, *folder.parents) if not p.exists()]):
        try:
            missing.mkdir(mode=0o700)
        except FileExistsError:  # another worker made it first
            pass


def _untrusted_folder(real: Path) -> str | None:
    """Why another user could change what the folder ``real`` (a resolved path) holds, or
    ``None``: the folder itself and every folder above it are checked."""
    return _untrusted(real) or next(
        (reason for above in real.parents if (reason := _untrusted(above, parent=True))), None
    )


def _trusted_files(library: Path) -> bool:
    """Whether the cached ``library`` and its checksum (where they exist) are regular files
    only this user (or root) can change; else a warning and ``False`` (they are rebuilt)."""
    for path in (library, _checksum_file(library)):
        if not os.path.lexists(path):
            continue
        reason = _untrusted(path) or (None if path.is_file() else f"{path} is not a file")
        if reason:
            log.warning("cached file not loaded: %s; rebuilding it", reason)
            return False
    return True


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
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(target, 0o755 & ~umask)  # the compiler's umask may let the group write
        os.replace(target, library)
    atomic_write_text(_checksum_file(library), checksum + "\n", mode=0o644 & ~umask)
    log.info("compiled %s", library)
