"""User data → :class:`canonid.kernel.dataset.Dataset`: CSV files, ``.npz`` arrays and objects
shaped like ``nonlinear_benchmarks.Input_output_data``.

Every loader reads the project's time convention (see :mod:`canonid.kernel.dataset`): row ``t``
holds ``u[t]`` and ``y[t]``, where ``u[t]`` acts after ``y[t]`` is measured. Loaded data go into one
split, ``"train"``; :func:`split_train_val` then cuts a validation set off it.

* :func:`load_csv` — one file or several. Columns are named; ``inputs`` and ``outputs`` pick
  them. Either every file is one experiment, or ``experiment_column`` names a column whose value
  identifies the experiment of each row (experiments in order of first appearance, rows in file
  order; the rows of one experiment must be contiguous). A time column in seconds
  (``time_column``, else one named ``t`` or ``time``: :data:`TIME_COLUMNS`) gives the sampling
  time ``dt``: its steps must be uniform, and a ``dt`` given beside it must agree with them
  (``time_column=""`` switches the column off, to read the rows as samples every ``dt``); a time
  that goes back within a record warns that records were joined (name the
  ``experiment_column``). Without a time column ``dt`` (seconds) is required. A file separated
  by ``;`` or tabs is named so. Files are UTF-8 text, read as a stream; each column read is
  named once in the header and every cell of it is a finite number in plain notation (ASCII
  digits, optional sign, decimal point and exponent: not ``1_000`` or ``１２``, which ``float``
  reads).
* :func:`load_npz` — arrays ``u`` and ``y``, each ``(T, n)`` for one experiment or ``(N, T, n)``
  for ``N`` of equal length, or pairs ``u_0, y_0, u_1, y_1, …`` for experiments of any length;
  optional ``y_clean`` (same layout) and a scalar ``dt`` (else the ``dt`` argument).
* :func:`from_io_data` — one object or a sequence with attributes ``u``, ``y``,
  ``sampling_time`` and optionally ``state_initialization_window_length`` (kept in the
  metadata as ``n_init``, the samples a score must skip).
"""

from __future__ import annotations

import codecs
import csv
import io
import itertools
import logging
import math
import operator
import os
import re
import stat
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from canonid.kernel.dataset import Dataset, Trajectory, dt_problem
from canonid.kernel.errors import DataError, ShapeError
from canonid.kernel.io import read_json, read_npz, sha256_bytes, sha256_file

__all__ = [
    "data_checksum",
    "from_io_data",
    "is_dataset",
    "load_csv",
    "load_data",
    "load_npz",
    "plain_float",
    "regular_file",
    "split_train_val",
]

PathLike = str | os.PathLike[str]

log = logging.getLogger(__name__)

#: the header names (compared in lower case) read as a time column in seconds when none is named
TIME_COLUMNS = ("t", "time", "t_s", "time_s", "t [s]", "time [s]", "t (s)", "time (s)")
#: the relative spread of a time column's steps still read as one sampling time (printed times
#: are rounded)
TIME_STEP_RTOL = 1e-3


def _check_dt(dt: Any, where: str) -> float:
    try:
        value = float(dt)
    except (TypeError, ValueError):
        raise DataError(
            f"{where}: sampling time dt must be a number of seconds, got {dt!r}"
        ) from None
    problem = dt_problem(value)
    if problem:
        raise DataError(f"{where}: {problem}")
    return value


def _trajectory(
    u: Any, y: Any, where: str, y_clean: Any = None, info: dict[str, Any] | None = None
) -> Trajectory:
    try:
        return Trajectory(u=u, y=y, y_clean=y_clean, info=info or {})
    except ShapeError as exc:
        raise DataError(f"{where}: {exc}") from None


def _dataset(
    trajs: Sequence[Trajectory],
    *,
    dt: float,
    input_names: Sequence[str] | None,
    output_names: Sequence[str] | None,
    metadata: dict[str, Any],
    where: str,
) -> Dataset:
    if not trajs:
        raise DataError(f"{where}: no experiments found")
    n_u, n_y = trajs[0].n_u, trajs[0].n_y
    names_u = tuple(input_names or (f"u{i + 1}" for i in range(n_u)))
    names_y = tuple(output_names or (f"y{i + 1}" for i in range(n_y)))
    if len(names_u) != n_u or len(names_y) != n_y:
        raise DataError(
            f"{where}: {len(names_u)} input and {len(names_y)} output name(s) for data with "
            f"n_u={n_u}, n_y={n_y}"
        )
    try:
        return Dataset(
            splits={"train": tuple(trajs)},
            dt=dt,
            input_names=names_u,
            output_names=names_y,
            metadata=metadata,
        )
    except ShapeError as exc:
        raise DataError(f"{where}: {exc}") from None


# -------------------------------------------------------------------------------------- files
_NOT_REGULAR = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
)


def regular_file(path: Path, what: str) -> Path:
    """``path`` if it is a regular file (or a link to one); else a :class:`DataError` saying
    what it is instead: reading a FIFO or a device could block, or never end."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise DataError(f"{what} not found: {path}") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(mode):
        kind = next((name for test, name in _NOT_REGULAR if test(mode)), "a special file")
        raise DataError(f"{path} is {kind}, not a regular file; expected a {what}")
    return path


# ---------------------------------------------------------------------------------------- CSV
#: rows whose cells are converted to float64 at once: the chunk's Python strings (~70 bytes a
#: cell) are all the loader holds besides the arrays, so memory follows the numbers, not the text
_CHUNK_ROWS = 1 << 15

#: a number in plain notation: ASCII digits, an optional sign, point and exponent. ``float``
#: accepts more (``1_000``, non-ASCII digits such as ``１２``), which a CSV file should not hold
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: the spellings of NaN and infinity that ``float`` reads: refused as not finite, not as text
_NON_FINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
#: a character outside plain notation and the spaces around it: a chunk of cells without one
#: needs no check per cell, as ``float`` then accepts exactly the cells of plain notation
_NOT_PLAIN = re.compile(r"[^0-9eE+\-. \t]")
_EXPECTED = "expected plain decimal notation such as 12, -0.5 or 1.5e-3"


def plain_float(text: str) -> float:
    """``float(text)`` of a number in plain notation, or of a spelling of NaN or infinity (for
    the caller to refuse as not finite); a ValueError for anything else ``float`` would read
    (``1_000``, ``１２``, ``٣``). Spaces around the number are ignored."""
    text = text.strip()
    if _NUMBER.fullmatch(text) or _NON_FINITE.fullmatch(text):
        return float(text)
    raise ValueError(f"{text!r} is not a number in plain notation")


def _cell(cell: str, path: Path, line: int, column: str) -> float:
    """One cell as a finite float, or a :class:`DataError` naming its line and column."""
    where = f"{path}, line {line}, column {column!r}: {cell.strip()!r}"
    try:
        value = plain_float(cell)
    except ValueError:
        raise DataError(f"{where} is not a number ({_EXPECTED})") from None
    if not math.isfinite(value):
        raise DataError(f"{where} is not finite")
    return value


class _Table:
    """The picked cells of the data rows, converted to one float64 ``(rows, columns)`` array a
    chunk at a time."""

    def __init__(self, path: Path, columns: Sequence[str]) -> None:
        self.path, self.columns = path, list(columns)
        self.cells: list[tuple[str, ...]] = []  # the pending chunk: one tuple per row
        self.lines: list[int] = []  # its rows' line numbers, for the messages
        self.blocks: list[np.ndarray] = []
        self.rows = 0

    def add(self, cells: tuple[str, ...], line: int) -> None:
        self.cells.append(cells)
        self.lines.append(line)
        self.rows += 1
        if len(self.cells) == _CHUNK_ROWS:
            self.flush()

    def flush(self) -> None:
        """Convert the pending chunk (its first bad cell, in file order, raises)."""
        cells, lines = self.cells, self.lines
        self.cells, self.lines = [], []
        if cells:
            self.blocks.append(self._convert(cells, lines))

    def _convert(self, cells: list[tuple[str, ...]], lines: list[int]) -> np.ndarray:
        block = self._plain(cells)
        if block is None:  # cell by cell, in file order, so that the first bad cell is named
            block = np.empty((len(cells), len(self.columns)))
            for i, (row, line) in enumerate(zip(cells, lines)):
                for j, (cell, column) in enumerate(zip(row, self.columns)):
                    block[i, j] = _cell(cell, self.path, line, column)
        return block

    def _plain(self, cells: list[tuple[str, ...]]) -> np.ndarray | None:
        """The chunk as floats if every cell is a finite number in plain notation (one search
        per column tells, then ``float`` maps the column); else None."""
        block = np.empty((len(cells), len(self.columns)))
        for j, column in enumerate(zip(*cells)):
            if _NOT_PLAIN.search("".join(column)):
                return None
            try:
                block[:, j] = np.fromiter(map(float, column), np.float64, len(column))
            except ValueError:  # a malformed number such as "1e" or "1.2.3", or an empty cell
                return None
        return block if np.isfinite(block).all() else None

    def array(self) -> np.ndarray:
        self.flush()
        return self.blocks[0] if len(self.blocks) == 1 else np.concatenate(self.blocks)


def _first_bad_utf8_line(path: Path) -> int:
    """The line of the first byte of ``path`` that is not UTF-8, read in blocks."""
    decoder = codecs.getincrementaldecoder("utf-8")()
    newlines = 0
    with path.open("rb") as f:
        for block in itertools.chain(iter(lambda: f.read(1 << 20), b""), [b""]):
            try:
                decoder.decode(block, final=not block)
            except UnicodeDecodeError as exc:
                # exc.object: the bytes held back from the last block (no newline) + this one
                return newlines + exc.object[: exc.start].count(b"\n") + 1
            newlines += block.count(b"\n")
    return newlines + 1


#: one experiment of a CSV file: its key (the experiment column's value) and rows [start, stop)
_Run = tuple[str, int, int]


def _read_csv(
    path: Path, columns: Sequence[str], experiment_column: str | None
) -> tuple[list[_Run], np.ndarray]:
    """Stream ``path`` (UTF-8 CSV) into the float64 table of ``columns`` and its experiments."""
    regular_file(path, "CSV file")
    with path.open("rb") as raw:
        text = io.TextIOWrapper(raw, encoding="utf-8-sig", newline="")
        reader = csv.reader(text)
        try:
            return _parse_csv(path, reader, columns, experiment_column)
        except csv.Error as exc:
            raise DataError(f"{path}, line {reader.line_num}: not CSV text ({exc})") from None
        except UnicodeDecodeError:
            raise DataError(f"{path}, line {_first_bad_utf8_line(path)}: not UTF-8 text") from None


def _parse_csv(
    path: Path, reader: Any, columns: Sequence[str], experiment_column: str | None
) -> tuple[list[_Run], np.ndarray]:
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise DataError(f"{path}: empty file (expected a header row)") from None
    wanted = [*columns, *([experiment_column] if experiment_column else [])]
    missing = [c for c in wanted if c not in header]
    if missing:
        _refuse_separator(path, header, missing)
        raise DataError(f"{path}: no column(s) {missing}; the header has {header}")
    for name in dict.fromkeys(wanted):
        places = [str(i + 1) for i, h in enumerate(header) if h == name]
        if len(places) > 1:
            raise DataError(
                f"{path}: the header names column {name!r} {len(places)} times (columns "
                f"{', '.join(places[:-1])} and {places[-1]}); a column read must be named once"
            )
    pick = operator.itemgetter(*(header.index(c) for c in columns))  # ≥ 2 columns: a tuple
    exp_index = header.index(experiment_column) if experiment_column else None
    width = len(header)
    table = _Table(path, columns)
    starts: list[tuple[str, int]] = []  # (key, first row) of each experiment, in file order
    first_line: dict[str, int] = {}
    try:
        for row in reader:
            if not row or not (row[0].strip() or "".join(row).strip()):
                continue  # a blank line, or one of empty fields
            line = reader.line_num
            if len(row) != width:
                raise DataError(f"{path}, line {line}: {len(row)} fields, the header has {width}")
            key = "" if exp_index is None else row[exp_index].strip()
            if not starts or key != starts[-1][0]:
                if key in first_line:
                    raise DataError(
                        f"{path}, line {line}: experiment {key!r} (column {experiment_column!r}) "
                        f"started on line {first_line[key]} and other experiments came between; "
                        "each experiment's rows must be contiguous, in time order"
                    )
                first_line[key] = line
                starts.append((key, table.rows))
            table.add(pick(row), line)
    except (DataError, csv.Error, UnicodeDecodeError):
        table.flush()  # a bad cell on an earlier line is the first problem: it is named instead
        raise
    if not table.rows:
        raise DataError(f"{path}: no data rows under the header")
    stops = [start for _, start in starts[1:]] + [table.rows]
    return [(key, start, stop) for (key, start), stop in zip(starts, stops)], table.array()


def _refuse_separator(path: Path, header: list[str], missing: list[str]) -> None:
    """A header that holds some of the columns ``missing`` once split at ``;`` or tabs instead
    of commas is named so (such files often write decimal commas too)."""
    for separator, name in ((";", "';'"), ("\t", "tabs")):
        fields = {f.strip() for h in header for f in h.split(separator)}
        if any(separator in h for h in header) and fields & set(missing):
            raise DataError(
                f"{path}: the header {','.join(header)!r} is separated by {name}, not commas; "
                "save the file as comma-separated values, with '.' as the decimal point"
            )


def load_csv(
    paths: PathLike | Sequence[PathLike],
    *,
    inputs: Sequence[str],
    outputs: Sequence[str],
    dt: float | None = None,
    experiment_column: str | None = None,
    time_column: str | None = None,
) -> Dataset:
    """Read experiments from CSV (see the module docstring); one ``"train"`` split.

    ``experiment_column``: ``None`` or ``""`` for none. ``time_column``: a column of times in
    seconds, ``""`` for none, ``None`` for one named as in :data:`TIME_COLUMNS` if the header
    has it. ``dt``: the sampling time in seconds, else the time column's step.
    """
    files = [Path(paths)] if isinstance(paths, (str, os.PathLike)) else [Path(p) for p in paths]
    where = ", ".join(str(f) for f in files)
    if not files:
        raise DataError("load_csv: no files given")
    inputs, outputs = [str(c) for c in inputs], [str(c) for c in outputs]
    if not inputs or not outputs:
        raise DataError(f"{where}: name at least one input and one output column")
    overlap = sorted(set(inputs) & set(outputs))
    if overlap:
        raise DataError(f"{where}: column(s) {overlap} given as both input and output")
    experiment_column = experiment_column or None
    if time_column and time_column in [*inputs, *outputs, experiment_column]:
        raise DataError(f"{where}: column {time_column!r} given as the time column and another")
    given_dt = None if dt is None else _check_dt(dt, where)
    n_u, n_y = len(inputs), len(outputs)
    trajs: list[Trajectory] = []
    labels: list[str] = []
    clocks: list[_Clock] = []
    for path in files:
        clock = _time_column(path, time_column, [*inputs, *outputs, experiment_column])
        columns = [*inputs, *outputs, *([clock] if clock else [])]
        runs, table = _read_csv(path, columns, experiment_column)
        for key, start, stop in runs:
            sub = table[start:stop]  # a view: each experiment's rows are contiguous
            name = path.name if experiment_column is None else key
            label = name if experiment_column is None else f"{path.name}:{experiment_column}={key}"
            # the record's name in figures: the file, or the experiment column's value
            shown = name if experiment_column is None else f"{experiment_column} = {key}"
            u, y = sub[:, :n_u], sub[:, n_u : n_u + n_y]
            at = f"{path}, experiment {name!r}"
            trajs.append(_trajectory(u, y, at, info={"experiment": shown}))
            labels.append(label)
            if clock:
                clocks.append(_Clock(path, clock, start, sub[:, -1]))
    if not clocks and given_dt is None:
        raise DataError(
            f"{where}: CSV data need the sampling time: give dt in seconds (CLI: --dt SECONDS), "
            "or a time column (CLI: --time-column COL)"
        )
    dt = _sampling_time(clocks, given_dt, where)
    metadata = {
        "source": "csv",
        "files": [str(f) for f in files],
        "experiment_column": experiment_column,
        "time_column": clocks[0].column if clocks else None,
        "dt_from": "given" if given_dt is not None else "time column",
        "experiments": labels,
    }
    return _dataset(
        trajs, dt=dt, input_names=inputs, output_names=outputs, metadata=metadata, where=where
    )


def _time_column(path: Path, asked: str | None, taken: Sequence[str | None]) -> str | None:
    """The time column of ``path``: ``asked`` (``""``: none), else the one header name of
    :data:`TIME_COLUMNS` that is not a column ``taken``, if any."""
    if asked is not None:
        return asked or None
    header = _header(regular_file(path, "CSV file"))  # a FIFO is named, not opened
    found = [h for h in header if h.lower() in TIME_COLUMNS and h not in taken]
    return found[0] if len(found) == 1 else None


def _header(path: Path) -> list[str]:
    """The stripped column names of ``path``'s first line (``[]`` when it cannot be read; the
    reader then names the problem)."""
    try:
        with path.open(newline="", encoding="utf-8-sig", errors="replace") as f:
            return [h.strip() for h in next(csv.reader(f), [])]
    except (OSError, csv.Error):
        return []


@dataclass(frozen=True)
class _Clock:
    """The time column of one experiment: ``times`` of its rows, the first at data row
    ``first_row`` (0-based, blank lines not counted) of ``path``."""

    path: Path
    column: str
    first_row: int
    times: np.ndarray

    def steps(self) -> np.ndarray:
        """The steps between rows, where the time goes forward; a step back (a restart: two
        records joined) warns, a time that stays is refused."""
        steps = np.diff(self.times)
        back = np.flatnonzero(steps < 0)
        if back.size:
            row = int(back[0]) + 1
            line = _line_of_row(self.path, self.first_row + row)
            log.warning(
                "%s, line %d: time column %r goes back from %g to %g (%d time(s) in all), so "
                "the rows before and after are joined into one record; if they are separate "
                "experiments, name the column that tells them apart (CLI: --experiment-column "
                "COL)",
                self.path,
                line,
                self.column,
                self.times[row - 1],
                self.times[row],
                back.size,
            )
        still = np.flatnonzero(steps == 0)
        if still.size:
            row = int(still[0]) + 1
            raise DataError(
                f"{self.path}, line {_line_of_row(self.path, self.first_row + row)}: time "
                f"column {self.column!r} repeats {self.times[row]:g}; each row is one sample"
            )
        return steps[steps > 0]


def _sampling_time(clocks: Sequence[_Clock], given: float | None, where: str) -> float:
    """The step of the time columns (uniform within :data:`TIME_STEP_RTOL`, rounded to 12
    significant digits), or ``given`` where none has two rows; steps that are not uniform, and a
    ``given`` dt that disagrees with the step beyond :data:`TIME_STEP_RTOL`, are refused, naming
    ``time_column=""`` (CLI: ``--time-column none``), which reads the rows as samples every
    ``dt``."""
    steps = [(c, c.steps()) for c in clocks]
    forward = [s for _, s in steps if s.size]
    if not forward:
        if given is None:
            raise DataError(f"{where}: the time column has no two rows to give dt; give --dt")
        return given
    every = np.concatenate(forward)
    step = float(f"{every.sum() / every.size:.12g}")
    spread_tol = TIME_STEP_RTOL * step
    name = ", ".join(sorted({repr(c.column) for c in clocks}))
    if float(np.abs(every - step).max()) > spread_tol:
        clock = next(c for c, s in steps if s.size and np.abs(s - step).max() > spread_tol)
        summary = f"steps from {every.min():g} s to {every.max():g} s"
        how = (
            "every dt, switch the column off and give dt (CLI: --time-column none --dt SECONDS)"
            if given is None
            else f"every dt = {given:g} s as given, switch the column off (CLI: --time-column none)"
        )
        raise DataError(
            f"{clock.path}: time column {name} is not uniformly spaced ({summary}); to read the "
            f"rows as samples {how}"
        )
    if given is not None and not math.isclose(step, given, rel_tol=TIME_STEP_RTOL):
        raise DataError(
            f"{where}: dt = {given:g} s was given, but time column {name} steps by {step:g} s; "
            "leave dt out to use the time column, or switch the column off to read the rows as "
            f"samples every {given:g} s (CLI: --time-column none)"
        )
    return given if given is not None else _check_dt(step, f"{where}: time column {name}")


def _line_of_row(path: Path, row: int) -> int:
    """The line of data row ``row`` (0-based, blank lines not counted, as :func:`_parse_csv`
    counts them) of ``path``, read again: only a message needs it."""
    with path.open("rb") as raw:
        reader = csv.reader(io.TextIOWrapper(raw, encoding="utf-8-sig", newline=""))
        next(reader, None)
        seen = -1
        for cells in reader:
            if cells and (cells[0].strip() or "".join(cells).strip()):
                seen += 1
                if seen == row:
                    return reader.line_num
    return 0


# ---------------------------------------------------------------------------------------- npz
def load_npz(
    path: PathLike,
    *,
    dt: float | None = None,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
) -> Dataset:
    """Read experiments from an ``.npz`` of arrays (see the module docstring)."""
    p = regular_file(Path(path), "array file (.npz)")
    arrays = read_npz(p, what="array file")
    if "dt" in arrays:
        stored = arrays.pop("dt")
        if stored.size != 1:
            raise DataError(
                f"{p}: array 'dt' must hold one number (seconds), got shape {stored.shape}"
            )
        file_dt = _check_dt(stored.reshape(-1)[0], str(p))
        if dt is not None and not math.isclose(_check_dt(dt, str(p)), file_dt):
            raise DataError(f"{p}: holds dt = {file_dt} but dt = {dt} was given")
        dt = file_dt
    if dt is None:
        raise DataError(f"{p}: no array 'dt' in the file; give the sampling time (dt)")
    dt = _check_dt(dt, str(p))
    trajs: list[Trajectory] = []
    if "u" in arrays or "y" in arrays:
        if "u" not in arrays or "y" not in arrays:
            raise DataError(f"{p}: needs both arrays 'u' and 'y'; it has {sorted(arrays)}")
        u, y, yc = arrays["u"], arrays["y"], arrays.get("y_clean")
        if u.ndim == 3 or y.ndim == 3:
            if u.ndim != 3 or y.ndim != 3 or u.shape[0] != y.shape[0]:
                raise DataError(
                    f"{p}: 'u' {u.shape} and 'y' {y.shape} must both be (N, T, n) with equal N"
                )
            if yc is not None and (yc.ndim != 3 or yc.shape[0] != u.shape[0]):
                raise DataError(f"{p}: 'y_clean' {yc.shape} must be (N, T, n) like 'y' {y.shape}")
            for i in range(u.shape[0]):
                trajs.append(
                    _trajectory(u[i], y[i], f"{p}, experiment {i}", None if yc is None else yc[i])
                )
        else:
            trajs.append(_trajectory(u, y, str(p), yc))
    else:
        keys = sorted(
            (int(m.group(1)) for k in arrays if (m := re.fullmatch(r"u_(\d+)", k))),
        )
        if not keys:
            raise DataError(
                f"{p}: expected arrays 'u' and 'y', or 'u_0', 'y_0', 'u_1', …; found "
                f"{sorted(arrays)}"
            )
        for i in keys:
            if f"y_{i}" not in arrays:
                raise DataError(f"{p}: has 'u_{i}' but no 'y_{i}'")
            trajs.append(
                _trajectory(
                    arrays[f"u_{i}"],
                    arrays[f"y_{i}"],
                    f"{p}, experiment {i}",
                    arrays.get(f"y_clean_{i}"),
                )
            )
    return _dataset(
        trajs,
        dt=dt,
        input_names=input_names,
        output_names=output_names,
        metadata={"source": "npz", "file": str(p)},
        where=str(p),
    )


# --------------------------------------------------------------------- Input_output_data-like
def from_io_data(
    data: Any,
    *,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
) -> Dataset:
    """Experiments from objects shaped like ``nonlinear_benchmarks.Input_output_data``
    (attributes ``u``, ``y``, ``sampling_time``, optionally
    ``state_initialization_window_length``); one object or a sequence of them."""
    items = [data] if hasattr(data, "u") else list(data)
    if not items:
        raise DataError("from_io_data: no experiments given")
    trajs, dts, n_inits = [], [], []
    for i, item in enumerate(items):
        where = f"input/output data object {i}"
        for attr in ("u", "y", "sampling_time"):
            if not hasattr(item, attr):
                raise DataError(f"{where}: has no attribute {attr!r}")
        trajs.append(_trajectory(item.u, item.y, where))
        dts.append(_check_dt(item.sampling_time, where))
        n_init = getattr(item, "state_initialization_window_length", None)
        if n_init is not None:
            n_inits.append(int(n_init))
    if any(not math.isclose(d, dts[0]) for d in dts):
        raise DataError(f"from_io_data: the experiments have different sampling times {dts}")
    metadata: dict[str, Any] = {"source": "Input_output_data"}
    if n_inits:
        metadata["n_init"] = max(n_inits)
    return _dataset(
        trajs,
        dt=dts[0],
        input_names=input_names,
        output_names=output_names,
        metadata=metadata,
        where="from_io_data",
    )


# ---------------------------------------------------------------------------------- dispatch
def is_dataset(path: PathLike) -> bool:
    """Whether :func:`load_data` reads ``path`` as a canonid dataset (with its own names and
    sampling time) rather than as CSV or an ``.npz`` of arrays."""
    p = Path(path)
    if p.is_dir():
        return (p / "dataset.npz").is_file()
    return p.suffix.lower() in (".npz", ".json") and p.with_suffix(".json").is_file()


def data_checksum(path: PathLike) -> str:
    """The SHA-256 of what :func:`load_data` reads at ``path``: a canonid dataset's recorded
    checksum (every load validates it), a file's bytes, or a folder of CSV files' names and
    bytes (the files :func:`load_data` reads, in its order)."""
    p = Path(path)
    if is_dataset(p):
        meta = (p / "dataset.json") if p.is_dir() else p.with_suffix(".json")
        header = read_json(meta, what="dataset metadata")
        checksum = header.get("checksum_sha256") if isinstance(header, dict) else None
        if not isinstance(checksum, str):
            raise DataError(f"{meta}: no field 'checksum_sha256' (not canonid dataset metadata)")
        return checksum
    if p.is_dir():
        files = sorted(p.glob("*.csv"))
        if not files:
            raise DataError(f"{p}: a folder without dataset.npz or CSV files")
        listing = "".join(f"{f.name}\t{sha256_file(f)}\n" for f in files)
        return sha256_bytes(listing.encode())
    return sha256_file(regular_file(p, "data file"))


def load_data(
    path: PathLike,
    *,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    dt: float | None = None,
    experiment_column: str | None = None,
    time_column: str | None = None,
) -> Dataset:
    """Read ``path`` by its kind: a canonid dataset (``.npz`` with its ``.json`` sidecar, or a
    folder holding ``dataset.npz``), a CSV file or a folder of CSV files (one experiment each,
    in name order; the options of :func:`load_csv`), or an ``.npz`` of arrays."""
    p = Path(path)
    if is_dataset(p):
        return Dataset.load(p)
    if p.is_dir():
        files = sorted(p.glob("*.csv"))
        if not files:
            raise DataError(f"{p}: a folder without dataset.npz or CSV files")
        return _csv(files, inputs, outputs, dt, experiment_column, time_column)
    regular_file(p, "data file")
    if p.suffix.lower() == ".csv":
        return _csv([p], inputs, outputs, dt, experiment_column, time_column)
    if p.suffix.lower() == ".npz":
        return load_npz(p, dt=dt)
    raise DataError(f"{p}: unknown data format (expected a dataset, .csv or .npz)")


def _csv(
    files: list[Path],
    inputs: Sequence[str] | None,
    outputs: Sequence[str] | None,
    dt: float | None,
    experiment_column: str | None,
    time_column: str | None,
) -> Dataset:
    where = ", ".join(str(f) for f in files)
    if not inputs or not outputs:
        raise DataError(
            f"{where}: CSV data need the input and output column names (CLI: --inputs COL,... "
            f"--outputs COL,...); the header has {_csv_header(files[0])}"
        )
    return load_csv(
        files,
        inputs=inputs,
        outputs=outputs,
        dt=dt,
        experiment_column=experiment_column,
        time_column=time_column,
    )


def _csv_header(path: Path) -> str:
    """The column names of ``path``'s first line, quoted, for an error message."""
    names = [n for n in _header(path) if n]
    return ", ".join(repr(n) for n in names) if names else "no column names"


# ---------------------------------------------------------------------------------- splits
def split_train_val(
    dataset: Dataset, *, val_fraction: float = 0.2, record_tails: bool = False
) -> Dataset:
    """Cut a ``"val"`` split off the ``"train"`` split.

    Several experiments: the last ``⌈val_fraction · N⌉`` (in order) become validation, at least
    one stays for training. One experiment, or any number with ``record_tails=True``: the first
    ``⌊(1 − val_fraction) T⌋`` samples of every record stay training data and the rest of that
    record becomes validation (``info["samples"]`` holds each part's ``[start, stop)`` within its
    record). Other splits are kept as they are.
    """
    if not 0 < val_fraction < 1:
        raise DataError(f"val_fraction must be in (0, 1), got {val_fraction}")
    train = dataset.split("train")
    if "val" in dataset.splits:
        raise DataError("the dataset already has a 'val' split")
    if len(train) >= 2 and not record_tails:
        n_val = min(max(1, math.ceil(val_fraction * len(train))), len(train) - 1)
        new_train, new_val = train[: len(train) - n_val], train[len(train) - n_val :]
        how = f"last {n_val} of {len(train)} experiments"
    else:
        heads, tails = [], []
        for i, tr in enumerate(train):
            cut = int((1 - val_fraction) * tr.T)
            if not _splits_at(tr.T, val_fraction):
                raise DataError(
                    f"{_record_name(dataset, i)} has {tr.T} samples, too few to cut a validation "
                    f"tail of --val-fraction {val_fraction:g} (at least 2 samples each side): it "
                    f"needs at least {_fewest_samples(val_fraction)} samples"
                )
            heads.append(tr.part(0, cut, samples=[0, cut]))
            tails.append(tr.part(cut, tr.T, samples=[cut, tr.T]))
        new_train, new_val = tuple(heads), tuple(tails)
        share = f"the last {val_fraction:.0%} of"
        how = (
            f"samples {cut}…{train[0].T - 1} of the single record"
            if len(train) == 1
            else f"{share} every one of the {len(train)} records"
        )
    splits = {**dataset.splits, "train": new_train, "val": new_val}
    return Dataset(
        splits=splits,
        dt=dataset.dt,
        input_names=dataset.input_names,
        output_names=dataset.output_names,
        state_names=dataset.state_names,
        metadata={**dataset.metadata, "validation_split": how},
    )


def _splits_at(samples: int, val_fraction: float) -> bool:
    cut = int((1 - val_fraction) * samples)
    return cut >= 2 and samples - cut >= 2


def _fewest_samples(val_fraction: float) -> int:
    """The fewest samples a record needs for :func:`split_train_val` to leave 2 on each side."""
    # both parts grow with the length, so count up from just below the bounds 1/f and 2/(1 − f)
    samples = max(4, int(1 / val_fraction) - 1, int(2 / (1 - val_fraction)) - 1)
    while not _splits_at(samples, val_fraction):
        samples += 1
    return samples


def _record_name(dataset: Dataset, i: int) -> str:
    """``FILE: record 'NAME'`` of training record ``i``, from what the loader recorded."""
    meta = dataset.metadata  # the loader's own fields, or whatever a dataset.json held
    listed = meta.get("files", [meta.get("file")])
    files = [f for f in listed if isinstance(f, str)] if isinstance(listed, list) else []
    labels = meta.get("experiments")
    info = dataset.split("train")[i].info
    if isinstance(labels, list) and i < len(labels):
        name = repr(labels[i])
    elif "part" in info:
        name = repr(info["part"])
    else:
        name = str(i)
    return f"{', '.join(files)}: record {name}" if files else f"record {name}"
