"""File helpers shared by every layer: atomic writes, deterministic ``.npz``, checksums.

They live in the kernel, under every layer; they need only numpy.

* Atomic: content is written to a temporary file in the target folder, flushed, fsynced and
  renamed over the target, so a reader never sees a half-written file. ``durable=False`` skips
  the fsync (a killed process still leaves the old file or the new one; a power failure may
  lose or damage the file): for caches that are checked when read, such as generation parts.
* Safe in a folder someone else prepared: the temporary file has a unique name, created
  exclusively (``mkstemp``), so a symlink planted under a predictable temporary name is never
  written through; and the rename replaces a symlink planted at the target itself rather than
  the file it points to. Every file canonid writes goes through here: figures too
  (:func:`atomic_write_figure`), and copies (:func:`atomic_copy`, a folder
  :func:`atomic_copy_tree`).
* Deterministic: :func:`write_npz` fixes every zip timestamp and writes arrays in sorted key
  order, so the same arrays always give the same bytes (``np.savez`` stamps the current time).
* No pickle: arrays are written and read with ``allow_pickle=False``.
* A write that fails (a file where a folder should be, a full disk, a read-only file system)
  raises :class:`~canonid.kernel.errors.OutputError` naming the file, and leaves no temporary file.
* Appended, not replaced: :func:`append_line` adds one line to a log (the run folder's ledger of
  test reads) in one ``write`` to a file opened ``O_APPEND``, never through a symlink.
* No link followed inside a run folder: while a block runs :func:`confined` to a folder, every
  path below it that these helpers read, write, copy or make (:func:`make_folder`) is checked by
  :func:`check_inside`: no component below the folder may be a symbolic link, and a file read,
  appended to or copied may have no second (hard) link. A path that a record holds is resolved
  by :func:`run_path`: relative to the folder, and inside it.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import stat
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import IO, Any, Protocol

import numpy as np

from canonid.kernel.errors import DataError, OptionError, OutputError

__all__ = [
    "FIGURE_FORMATS",
    "append_line",
    "atomic_copy",
    "atomic_copy_tree",
    "atomic_write_bytes",
    "atomic_write_figure",
    "atomic_write_json",
    "atomic_write_text",
    "check_appendable",
    "check_inside",
    "confined",
    "figure_name",
    "guarded",
    "is_json_number",
    "is_outside_record",
    "jsonable",
    "make_folder",
    "npz_bytes",
    "read_json",
    "read_npz",
    "remove_stale_temporaries",
    "run_path",
    "sha256_bytes",
    "sha256_file",
    "write_npz",
]

_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)

#: the run folders whose paths the helpers below check (:func:`confined`), innermost last
_ROOTS: ContextVar[tuple[str, ...]] = ContextVar("canonid_confined_roots", default=())


@contextmanager
def confined(root: str | os.PathLike[str]) -> Iterator[Path]:
    """While the block runs, every path below ``root`` that this module's helpers read, write,
    copy or make is checked by :func:`check_inside` (``root`` itself is the user's choice and
    may be reached through links)."""
    token = _ROOTS.set((*_ROOTS.get(), os.path.abspath(root)))
    try:
        yield Path(root)
    finally:
        _ROOTS.reset(token)


def _below(root: str, path: str) -> bool:
    return path != root and path.startswith(root.rstrip(os.sep) + os.sep)


def check_inside(
    root: str | os.PathLike[str], path: str | os.PathLike[str], *, replaced: bool = False
) -> Path:
    """``path``, checked to be below the folder ``root`` without a link: every component below
    ``root`` that exists is no symbolic link (an intermediate one a folder), and the last, when
    a regular file, has no second hard link (``replaced``: the last is replaced by a rename, not
    opened, so a link there is replaced, not followed, and allowed). A missing component passes:
    it will be made. Anything else raises one :class:`OutputError` naming the path."""
    base, full = os.path.abspath(root), os.path.abspath(path)
    if not _below(base, full):
        raise OutputError(f"{path}: outside the run folder {root}; canonid keeps to the folder")
    parts = os.path.relpath(full, base).split(os.sep)
    current = base
    for depth, part in enumerate(parts, start=1):
        current = os.path.join(current, part)
        try:
            info = os.lstat(current)
        except FileNotFoundError:
            return Path(path)
        except OSError as exc:
            raise OutputError(f"{current}: cannot read ({exc.strerror})") from None
        last = depth == len(parts)
        if stat.S_ISLNK(info.st_mode) and not (last and replaced):
            raise OutputError(
                f"{current} is a symbolic link inside the run folder {root}; canonid follows no "
                "link there (remove it)"
            )
        if not last and not stat.S_ISDIR(info.st_mode):
            raise OutputError(f"{current} is not a folder; expected a folder of the run {root}")
        if last and not replaced and stat.S_ISREG(info.st_mode) and info.st_nlink > 1:
            raise OutputError(
                f"{current} has {info.st_nlink} hard links (the same file elsewhere too); canonid "
                "reads and writes only a run folder's own files (copy it, then remove the link)"
            )
    return Path(path)


def guarded(path: str | os.PathLike[str], *, replaced: bool = False) -> Path:
    """``path``, checked by :func:`check_inside` for each folder :func:`confined` holds it below
    (for a reader or writer outside this module: ``torch.load``, ``shutil.rmtree``)."""
    full = os.path.abspath(path)
    for root in _ROOTS.get():
        if _below(root, full):
            check_inside(root, full, replaced=replaced)
    return Path(path)


def make_folder(path: str | os.PathLike[str]) -> Path:
    """Make the folder ``path`` (and its parents), checked by :func:`guarded` first: no link is
    followed below a :func:`confined` folder; a failure is an :class:`OutputError` naming it."""
    guarded(path)
    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot make the folder {path}: {exc.strerror or exc}") from exc
    guarded(path)  # a link planted while it was made
    return Path(path)


def run_path(root: str | os.PathLike[str], recorded: Any, *, where: str) -> Path:
    """The path that a record (``where``: its file and field) holds, relative to the run folder
    ``root``: a relative path that stays inside the folder (``"."``: the folder itself), with no
    link below it (:func:`check_inside`); anything else is one :class:`DataError` naming the
    record."""
    if not isinstance(recorded, str) or not recorded or "\0" in recorded:
        raise DataError(f"{where}: expected a path relative to the run folder; got {recorded!r}")
    if os.path.isabs(recorded) or ".." in Path(recorded).parts:
        raise DataError(
            f"{where}: {recorded!r} is not a path inside the run folder (expected one relative "
            "to it, without '..')"
        )
    if recorded in (".", "./"):
        return Path(root)
    target = Path(root) / recorded
    try:
        check_inside(root, target)
    except OutputError as exc:
        raise DataError(f"{where}: {exc}") from None
    return target


# tempfile, zipfile and hashlib are imported where a write, an .npz or a checksum needs them:
# reading a CSV needs none of them, and canonid.load_data's start-up is measured


def atomic_write_bytes(
    path: str | os.PathLike[str], data: bytes, *, durable: bool = True, mode: int | None = None
) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + rename, fsynced when
    ``durable``); return the path. ``mode``: the new file's permission bits (default what a plain
    ``open()`` gives, 0666 less the umask)."""
    with _replacing(path, durable=durable, mode=mode) as fh:
        fh.write(data)
    return Path(path)


def atomic_copy(
    source: str | os.PathLike[str], path: str | os.PathLike[str], *, durable: bool = True
) -> Path:
    """Copy the bytes of ``source`` to ``path`` atomically (as :func:`atomic_write_bytes`, the
    new file with the mode a plain ``open()`` gives); return the path. A source that cannot be
    read raises :class:`OutputError` naming both files and leaves ``path`` as it was."""
    src, target = Path(source), Path(path)
    guarded(src)
    try:
        reader = open(src, "rb")  # closed by the with below
    except OSError as exc:
        raise OutputError(f"cannot copy {src} to {target}: {exc.strerror or exc}") from exc
    with reader, _replacing(target, durable=durable, mode=None) as fh:
        while True:
            try:
                chunk = reader.read(1 << 20)
            except OSError as exc:  # names the source; the writer names the target for its own
                raise OutputError(f"cannot copy {src} to {target}: {exc.strerror or exc}") from exc
            if not chunk:
                break
            fh.write(chunk)
    return target


#: the file formats figures are written in (``--figure-format``); the first is the default
FIGURE_FORMATS = ("png", "pdf", "svg")


def atomic_copy_tree(source: str | os.PathLike[str], path: str | os.PathLike[str]) -> Path:
    """Replace the folder ``path`` (if any) by a copy of the folder ``source``; return the path.
    The copy is made beside it under a hidden name (``.NAME.staged``), then the old folder is
    removed and the copy renamed: ``path`` is never a partial copy (an interruption leaves the
    old folder or none, and the hidden copy, which the next call replaces)."""
    import shutil

    def remove(entry: Path) -> None:  # a planted link is removed, never followed
        if entry.is_symlink() or entry.is_file():
            entry.unlink()
        elif entry.is_dir():
            shutil.rmtree(entry)

    src, target = Path(source), Path(path)
    staged = target.with_name(f".{target.name}.staged")
    guarded(src)
    guarded(target.parent)
    for folder, names, files in os.walk(src):  # a link inside a confined source is refused too
        for name in (*names, *files):
            guarded(os.path.join(folder, name))
    try:
        remove(staged)
        shutil.copytree(src, staged, symlinks=True)
        remove(target)
        staged.rename(target)
    except (OSError, shutil.Error) as exc:
        raise OutputError(f"cannot copy {src} to {target}: {exc}") from exc
    return target


def figure_name(name: str, figure_format: str) -> str:
    """``name.FORMAT``, the file name of a figure in ``figure_format``; an unknown format is
    refused in one line naming ``--figure-format``."""
    if figure_format not in FIGURE_FORMATS:
        raise OptionError(
            f"--figure-format {figure_format!r}: expected one of {', '.join(FIGURE_FORMATS)}"
        )
    return f"{name}.{figure_format}"


#: per format, the metadata that leaves out the writer's software and date stamps
_UNSTAMPED: dict[str, dict[str, None]] = {
    "png": {"Software": None},
    "pdf": {"Creator": None, "Producer": None, "CreationDate": None},
    "svg": {"Creator": None, "Date": None},
}


class Savefig(Protocol):
    """What :func:`atomic_write_figure` needs of a figure (a matplotlib ``Figure`` has it)."""

    def savefig(self, fname: Any, *, format: str | None = ..., **kwargs: Any) -> Any: ...


def atomic_write_figure(
    path: str | os.PathLike[str],
    figure: Savefig,
    *,
    format: str | None = None,
    durable: bool = True,
    stamped: bool = True,
    **savefig: Any,
) -> Path:
    """Render ``figure`` in memory (``figure.savefig(buffer, format=..., **savefig)``) and write
    the bytes to ``path`` atomically; return the path, exactly as given (matplotlib's own
    ``savefig(path)`` would follow a symlink planted there and append a suffix to a name
    without one). ``format`` defaults to the suffix of ``path`` (``png``, ``pdf``, ``svg``);
    ``stamped=False`` leaves out the software and date stamps of a PNG, PDF or SVG file."""
    target = Path(path)
    fmt = format or target.suffix.lstrip(".").lower() or None
    if not stamped and fmt in _UNSTAMPED:
        savefig["metadata"] = {**_UNSTAMPED[fmt], **savefig.get("metadata", {})}
    buffer = io.BytesIO()
    figure.savefig(buffer, format=fmt, **savefig)
    return atomic_write_bytes(target, buffer.getvalue(), durable=durable)


@contextmanager
def _replacing(
    path: str | os.PathLike[str], *, durable: bool, mode: int | None
) -> Iterator[IO[bytes]]:
    """A binary file whose content replaces ``path`` when the block ends without error: a
    unique temporary file created exclusively beside the target, renamed over it. Any failure
    leaves the target as it was and no temporary file; an ``OSError`` becomes an
    :class:`OutputError` naming the target."""
    import tempfile

    target = Path(path)
    guarded(target, replaced=True)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise OutputError(f"cannot write {target}: {exc.strerror or exc}") from exc
    try:
        # mkstemp creates the file 0600; give it the mode asked for, or what open() would give
        os.fchmod(fd, 0o666 & ~_umask() if mode is None else mode)
        with os.fdopen(fd, "wb") as fh:
            yield fh
            fh.flush()
            if durable:
                os.fsync(fh.fileno())
        os.replace(tmp, target)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OutputError(f"cannot write {target}: {exc.strerror or exc}") from exc
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


#: the names of :func:`_replacing`'s temporary files: ``.<target>.<mkstemp's 8 characters>.tmp``
TEMPORARY_NAME = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")


def remove_stale_temporaries(folder: str | os.PathLike[str], *, before: float) -> list[Path]:
    """Remove the temporary files of this module's writes (:data:`TEMPORARY_NAME`) last
    modified before ``before`` (a time stamp) from ``folder``, not below it: what a process
    killed in the middle of a write left. Only plain files go (never a symlink, nor what it
    points to); the caller holds the folder's lock, so no write of its own is in progress.
    Returns the files removed."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        if not TEMPORARY_NAME.fullmatch(entry.name):
            continue
        try:
            info = entry.stat(follow_symlinks=False)
            if stat.S_ISREG(info.st_mode) and info.st_mtime < before:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue  # gone already, or not ours to remove: leave it
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(
    path: str | os.PathLike[str], text: str, *, durable: bool = True, mode: int | None = None
) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"), durable=durable, mode=mode)


def atomic_write_json(path: str | os.PathLike[str], obj: Any, *, durable: bool = True) -> Path:
    """Write ``obj`` as indented, key-sorted JSON (deterministic bytes), atomically."""
    text = json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n"
    return atomic_write_text(path, text, durable=durable)


def jsonable(value: Any) -> Any:
    """A JSON-ready copy of ``value``: mappings with string keys, tuples and arrays as lists,
    numpy scalars as Python numbers, non-finite floats as ``None`` (JSON has no NaN), paths as
    strings. A value survives a round trip through JSON equal to its ``jsonable`` copy."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, Path):
        return str(value)
    return value


def is_json_number(value: Any) -> bool:
    """Whether a value read from JSON is a number (``true`` and ``false`` are not)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def is_outside_record(value: Any) -> bool:
    """Whether a value read from JSON is one record of a signal outside a span, as
    :meth:`canonid.coverage.OutsideRange.to_json` writes it: a string ``name``, a ``kind``
    ``input`` or ``output``, numbers ``span_low``, ``span_high``, ``share``, ``distance`` and
    ``beyond`` a number or null (the model's loader and the metrics' reader both check it)."""
    numbers = ("span_low", "span_high", "share", "distance")
    return (
        isinstance(value, Mapping)
        and isinstance(value.get("name"), str)
        and value.get("kind") in ("input", "output")
        and all(is_json_number(value.get(k)) for k in numbers)
        and (value.get("beyond") is None or is_json_number(value["beyond"]))
    )


def read_json(path: str | os.PathLike[str], *, what: str = "JSON file") -> Any:
    """Read a JSON file, turning every failure into a :class:`DataError` naming the file."""
    p = Path(path)
    guarded(p)
    if not p.is_file():
        raise DataError(f"{what} not found: {p}")
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{what} {p} is not valid JSON (corrupt or truncated): {exc}") from exc


def npz_bytes(arrays: Mapping[str, np.ndarray]) -> bytes:
    """The bytes of an uncompressed ``.npz`` holding ``arrays``, identical for identical input."""
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        for key in sorted(arrays):
            arr = np.ascontiguousarray(arrays[key])
            if arr.dtype == object:
                raise DataError(f"array {key!r} has dtype object; only numeric arrays are stored")
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_EPOCH)
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue())
    return buf.getvalue()


def write_npz(
    path: str | os.PathLike[str], arrays: Mapping[str, np.ndarray], *, durable: bool = True
) -> str:
    """Write ``arrays`` to ``path`` atomically and deterministically; return the SHA-256."""
    data = npz_bytes(arrays)
    atomic_write_bytes(path, data, durable=durable)
    return sha256_bytes(data)


def read_npz(path: str | os.PathLike[str], *, what: str = "array file") -> dict[str, np.ndarray]:
    """Read every array of an ``.npz`` (no pickle) of real numbers; anything else (not a zip,
    corrupt, truncated, complex or text arrays) raises DataError."""
    import zipfile

    p = Path(path)
    guarded(p)
    if not p.is_file():
        raise DataError(f"{what} not found: {p}")
    if not zipfile.is_zipfile(p):
        raise DataError(f"{what} {p} is not an .npz archive (a zip of .npy arrays)")
    try:
        with np.load(p, allow_pickle=False) as npz:
            arrays = {key: npz[key] for key in npz.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as exc:
        raise DataError(f"{what} {p} is corrupt or truncated: {exc}") from exc
    for key, arr in arrays.items():
        if arr.dtype.kind not in "biuf":  # complex, text, bytes, dates, records
            raise DataError(
                f"{what} {p}: array {key!r} has dtype {arr.dtype}; expected real numbers"
            )
    return arrays


def append_line(path: str | os.PathLike[str], line: str, *, what: str = "log") -> Path:
    """Append ``line`` (a newline is added) to the file at ``path``, created if missing.

    The file is opened ``O_APPEND`` and the line written with one ``write`` and fsynced, so
    lines appended by several processes never interleave and a line, once this returns, is
    on disk. ``O_NOFOLLOW``: a symbolic link at ``path`` is refused, never written through;
    so is anything but a regular file (a FIFO would block). Each refusal is one
    :class:`~canonid.kernel.errors.OutputError` naming the file and ``what`` it is.
    """
    import errno

    target = Path(path)
    guarded(target)
    data = (line.rstrip("\n") + "\n").encode("utf-8")
    flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    try:
        fd = os.open(target, flags, 0o666)  # the umask applies
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise _not_appendable(target, what, symlink=True) from None
        check_appendable(target, what=what)  # a folder or a FIFO there: named as such
        raise OutputError(f"{target}: cannot append to the {what}: {exc.strerror}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise _not_appendable(target, what, symlink=False)
        if info.st_nlink > 1:  # a hard link: appending would change the file elsewhere too
            raise OutputError(f"{target}: the {what} has {info.st_nlink} hard links; remove it")
        written = os.write(fd, data)
        if written != len(data):
            raise OutputError(f"{target}: the {what} took {written} of {len(data)} bytes")
        os.fsync(fd)
    except OSError as exc:
        if isinstance(exc, OutputError):
            raise
        raise OutputError(f"{target}: cannot append to the {what}: {exc.strerror}") from None
    finally:
        os.close(fd)
    return target


def check_appendable(path: str | os.PathLike[str], *, what: str = "log") -> None:
    """Refuse, as :func:`append_line` would, a ``path`` that is a symbolic link or something
    other than a regular file (a missing file passes: it will be created); for a command that
    appends only after minutes of work, so that it is refused before them."""
    target = Path(path)
    try:
        mode = os.lstat(target).st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISREG(mode):
        raise _not_appendable(target, what, symlink=stat.S_ISLNK(mode))


def _not_appendable(target: Path, what: str, *, symlink: bool) -> OutputError:
    if symlink:
        return OutputError(
            f"{target}: the {what} is a symbolic link; canonid appends only to a regular file "
            "of its own there (remove the link)"
        )
    return OutputError(f"{target}: the {what} is not a regular file; remove it")


def sha256_bytes(data: bytes) -> str:
    import hashlib

    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike[str]) -> str:
    import hashlib

    guarded(path)
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
