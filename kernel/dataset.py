"""The trajectory and dataset types that every layer takes: generation, identification,
analysis and the application.

Validation happens once: constructing a :class:`Trajectory` checks its shapes and finiteness,
and :class:`Dataset` the dimensions its trajectories share. Data from elsewhere (any objects with
``.u`` and ``.y``) become trajectories at the edge of a public function, through
:func:`as_trajectories` (or :meth:`Trajectory.of` for one); inside, code trusts the type.

Time alignment (the convention of every layer)
-----------------------------------------------
Sample ``t`` of a trajectory holds the state ``x[t]``, the measured output
``y[t] = h(x[t], u[t]) + w[t]`` (``y_clean[t]`` without the noise ``w[t]``), and the input ``u[t]``
that moves ``x[t]`` to ``x[t+1] = f(x[t], u[t])``. User data is read with the same convention.
A model with window ℓ predicting ``y[t]`` sees the samples ``t−ℓ … t−1`` (and ``u[t]`` when it has
feedthrough).

Storage
-------
``save(path)`` writes two files: ``path`` (an uncompressed ``.npz``, no pickle, deterministic bytes)
and its sidecar ``path.with_suffix(".json")`` holding the metadata, the per-trajectory ``info`` and
the SHA-256 checksum of the ``.npz``. Both are written atomically, the JSON last, so a dataset whose
JSON exists is complete. ``load`` validates the checksum, every shape and finiteness, and names
the file and field of any problem.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from canonid.kernel.errors import DataError, ShapeError, UnknownSplitError
from canonid.kernel.io import atomic_write_json, read_json, read_npz, sha256_file, write_npz
from canonid.kernel.validate import as_matrix

__all__ = ["DT_RANGE", "FORMAT_VERSION", "Dataset", "Trajectory", "as_trajectories", "dt_problem"]

FORMAT_VERSION = 1
#: the sampling times, in seconds, that data may have: 1 ns to about 30 years (a subnormal or
#: absurd one, such as 1e-320, would make every rate and frequency overflow)
DT_RANGE = (1e-9, 1e9)
_FIELDS = ("u", "y", "y_clean", "x", "reference")
SPLITS = ("train", "val", "test")


def dt_problem(dt: float) -> str | None:
    """Why ``dt`` is no sampling time in :data:`DT_RANGE` (``None``: it is one)."""
    low, high = DT_RANGE
    if not (np.isfinite(dt) and low <= dt <= high):
        return f"sampling time dt must be from {low:g} to {high:g} s, got {dt!r}"
    return None


def _check_header(header: Mapping[str, Any], where: Path) -> None:
    """Refuse dataset metadata whose fields have the wrong types, naming the field."""

    def names(value: Any) -> bool:
        return isinstance(value, list) and all(isinstance(v, str) for v in value)

    def count(value: Any) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and value >= 0

    version = header.get("format_version")
    if version != FORMAT_VERSION:
        raise DataError(
            f"{where}: field 'format_version' is {version!r}; this canonid reads version "
            f"{FORMAT_VERSION}"
        )
    checks = (
        ("checksum_sha256", "a SHA-256 hex string", lambda v: isinstance(v, str) and len(v) == 64),
        (
            "dt",
            "a number of seconds",
            lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
        ),
        ("input_names", "a list of strings", names),
        ("output_names", "a list of strings", names),
        ("state_names", "null or a list of strings", lambda v: v is None or names(v)),
        (
            "counts",
            "an object of split name → trajectory count",
            lambda v: isinstance(v, dict) and all(count(n) for n in v.values()),
        ),
        ("metadata", "an object", lambda v: isinstance(v, dict)),
    )
    for key, expected, ok in checks:
        if key not in header and key in ("metadata", "state_names"):
            continue
        if key not in header:
            raise DataError(f"{where}: missing field {key!r}")
        if not ok(header[key]):
            raise DataError(f"{where}: field {key!r} must be {expected}, got {header[key]!r:.60}")
    infos = header.get("trajectory_info")
    if infos is None:
        return
    counts = header["counts"]
    if not isinstance(infos, dict) or any(
        not isinstance(infos[k], list)
        or len(infos[k]) != counts.get(k)
        or not all(isinstance(i, dict) for i in infos[k])
        for k in infos
    ):
        raise DataError(
            f"{where}: field 'trajectory_info' must map each split to a list of one object per "
            "trajectory (as many as 'counts' says)"
        )


def _validated(fields: Mapping[str, Any], where: str) -> dict[str, np.ndarray | None]:
    """The arrays of a trajectory (``u``, ``y`` and those of ``y_clean``, ``x``, ``reference``
    given) as finite float64 ``(T, n)`` arrays, a 1-D array read as one column; errors begin with
    ``where`` and name the field."""

    def columns(name: str) -> np.ndarray:
        try:
            arr = np.asarray(fields[name], dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ShapeError(f"{where}: field {name!r} must be a numeric array ({exc})") from None
        return arr[:, None] if arr.ndim == 1 else arr

    u, y = columns("u"), columns("y")
    u = as_matrix(u, u.shape[1] if u.ndim == 2 else -1, f"{where}: field 'u'")
    y = as_matrix(y, y.shape[1] if y.ndim == 2 else -1, f"{where}: field 'y'")
    if len(u) != len(y):
        raise ShapeError(f"{where}: u has {len(u)} samples but y has {len(y)}")
    if len(u) == 0:
        raise ShapeError(f"{where}: no samples (T = 0)")
    out: dict[str, np.ndarray | None] = {"u": u, "y": y}
    for name in ("y_clean", "x", "reference"):
        value = fields.get(name)
        if value is None:
            out[name] = None
            continue
        arr = columns(name)
        cols = arr.shape[1] if arr.ndim == 2 else -1
        if name == "y_clean" and cols != y.shape[1]:
            raise ShapeError(
                f"{where}: field 'y_clean' must have shape ({len(u)}, {y.shape[1]}), "
                f"got {arr.shape}"
            )
        out[name] = as_matrix(arr, cols, f"{where}: field {name!r}", rows=len(u))
    return out


@dataclass(frozen=True)
class Trajectory:
    """One experiment (a flight, a run) of ``T`` samples; see the module docstring for alignment.

    The one trajectory type of every layer. Constructing one validates it (shapes, lengths,
    finiteness) and is the only place that does: code that receives a ``Trajectory`` trusts it.
    Objects of another type that have ``.u`` and ``.y`` become one through :meth:`of` (or a
    sequence of them through :func:`as_trajectories`), at the edge of a public function.

    Attributes:
        u: inputs, ``(T, n_u)``.
        y: measured outputs, ``(T, n_y)``.
        y_clean: noise-free outputs ``h(x, u)``, ``(T, n_y)``, when known.
        x: true states, ``(T, n_x)``, when known.
        reference: the reference the controller tracked, ``(T, n_r)``, when there is one.
        info: JSON-ready facts about this trajectory (seed, controller statistics, ...).
    """

    u: np.ndarray
    y: np.ndarray
    y_clean: np.ndarray | None = None
    x: np.ndarray | None = None
    reference: np.ndarray | None = None
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        arrays = _validated({k: getattr(self, k) for k in _FIELDS}, "trajectory")
        for name, value in arrays.items():
            object.__setattr__(self, name, value)
        object.__setattr__(self, "info", dict(self.info))

    @classmethod
    def _trusted(
        cls, arrays: Mapping[str, np.ndarray | None], info: Mapping[str, Any]
    ) -> Trajectory:
        """A trajectory of arrays already validated (by :func:`_validated` or as slices of a
        trajectory's), built without checking them again."""
        tr = object.__new__(cls)
        for name in _FIELDS:
            object.__setattr__(tr, name, arrays.get(name))
        object.__setattr__(tr, "info", dict(info))
        return tr

    @classmethod
    def of(cls, obj: Any, *, where: str = "trajectory") -> Trajectory:
        """``obj`` itself if it is a :class:`Trajectory`; else the trajectory of its arrays
        ``.u``, ``.y`` and, where it has them, ``.y_clean``, ``.x``, ``.reference`` (and a mapping
        ``.info``), validated once here. Errors begin with ``where``."""
        if isinstance(obj, cls):
            return obj
        if not (hasattr(obj, "u") and hasattr(obj, "y")):
            raise DataError(
                f"{where}: expected an object with arrays .u and .y, got {type(obj).__name__}"
            )
        arrays = _validated({k: getattr(obj, k, None) for k in _FIELDS}, where)
        info = getattr(obj, "info", None)
        return cls._trusted(arrays, info if isinstance(info, Mapping) else {})

    @property
    def T(self) -> int:
        return int(self.u.shape[0])

    @property
    def n_u(self) -> int:
        return int(self.u.shape[1])

    @property
    def n_y(self) -> int:
        return int(self.y.shape[1])

    def arrays(self) -> dict[str, np.ndarray]:
        """The fields that are present, by name."""
        return {k: getattr(self, k) for k in _FIELDS if getattr(self, k) is not None}

    def part(self, start: int, stop: int, **info: Any) -> Trajectory:
        """Samples ``start … stop−1`` of every field, ``info`` added to this trajectory's (a
        part of a valid trajectory is valid: nothing is checked again but its length)."""
        if not 0 <= start < stop <= self.T:
            raise ShapeError(
                f"samples [{start}, {stop}) are not a part of a trajectory of {self.T}"
            )
        parts = {k: v[start:stop] for k, v in self.arrays().items()}
        return Trajectory._trusted(parts, {**self.info, **info})


def as_trajectories(data: Any, *, what: str = "data") -> tuple[Trajectory, ...]:
    """``data`` (one trajectory or a sequence of them) as a tuple of :class:`Trajectory`.

    The edge of every public function that takes trajectories: a :class:`Trajectory` passes as
    it is, any other object with ``.u`` and ``.y`` is validated once (:meth:`Trajectory.of`).
    There must be at least one, all with the ``n_u`` and ``n_y`` of the first; errors begin with
    ``what`` and name the trajectory.
    """
    if hasattr(data, "u") and hasattr(data, "y"):
        items = [data]
    else:
        try:
            items = list(data)
        except TypeError:
            raise DataError(
                f"{what}: expected a trajectory or a sequence of them, got {type(data).__name__}"
            ) from None
    if not items:
        raise DataError(f"{what}: no trajectories")
    out = tuple(
        Trajectory.of(item, where=f"{what}, trajectory {i}") for i, item in enumerate(items)
    )
    n_u, n_y = out[0].n_u, out[0].n_y
    for i, tr in enumerate(out):
        if (tr.n_u, tr.n_y) != (n_u, n_y):
            raise ShapeError(
                f"{what}, trajectory {i}: has n_u={tr.n_u}, n_y={tr.n_y}; trajectory 0 has "
                f"n_u={n_u}, n_y={n_y}"
            )
    return out


@dataclass(frozen=True)
class Dataset:
    """Named splits of trajectories that share dimensions, names and sampling time.

    Attributes:
        splits: ``{"train": (...), "val": (...), "test": (...)}`` (other names are allowed).
        dt: sampling time in seconds.
        input_names, output_names: signal names (units in ``metadata["units"]`` when known).
        state_names: names of ``x`` when the true state is stored.
        metadata: JSON-ready facts (system, parameters, controller, noise, seeds, versions, ...).
    """

    splits: Mapping[str, Sequence[Trajectory]]
    dt: float
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    state_names: tuple[str, ...] | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        problem = dt_problem(self.dt)
        if problem:
            raise ShapeError(f"dataset {problem}")
        object.__setattr__(self, "input_names", tuple(self.input_names))
        object.__setattr__(self, "output_names", tuple(self.output_names))
        if self.state_names is not None:
            object.__setattr__(self, "state_names", tuple(self.state_names))
        splits = {str(k): tuple(v) for k, v in self.splits.items()}
        n_u, n_y = len(self.input_names), len(self.output_names)
        for split, trajs in splits.items():
            for i, tr in enumerate(trajs):
                where = f"split {split!r}, trajectory {i}"
                if tr.n_u != n_u or tr.n_y != n_y:
                    raise ShapeError(
                        f"{where}: has n_u={tr.n_u}, n_y={tr.n_y}; the dataset declares "
                        f"{n_u} input(s) {self.input_names} and {n_y} output(s) {self.output_names}"
                    )
                if tr.x is not None and self.state_names is not None:
                    if tr.x.shape[1] != len(self.state_names):
                        raise ShapeError(
                            f"{where}: x has {tr.x.shape[1]} columns, expected "
                            f"{len(self.state_names)} ({self.state_names})"
                        )
        object.__setattr__(self, "splits", splits)
        object.__setattr__(self, "metadata", dict(self.metadata))

    # ------------------------------------------------------------------ access
    @property
    def n_u(self) -> int:
        return len(self.input_names)

    @property
    def n_y(self) -> int:
        return len(self.output_names)

    def split(self, name: str) -> tuple[Trajectory, ...]:
        """The trajectories of split ``name``."""
        try:
            return tuple(self.splits[name])
        except KeyError:
            hint = (
                " (a CSV or .npz file's records are all 'train': cut a validation split off "
                "with canonid.datagen.loaders.split_train_val(data))"
                if name == "val" and set(self.splits) == {"train"}
                else ""
            )
            raise UnknownSplitError(
                f"dataset has no split {name!r}; it has {sorted(self.splits)}{hint}"
            ) from None

    def counts(self) -> dict[str, int]:
        return {k: len(v) for k, v in self.splits.items()}

    @classmethod
    def from_arrays(
        cls,
        u: Any,
        y: Any,
        *,
        dt: float,
        split: str = "train",
        input_names: Iterable[str] | None = None,
        output_names: Iterable[str] | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> Dataset:
        """A one-split dataset from arrays: ``u`` ``(T, n_u)`` and ``y`` ``(T, n_y)`` for one
        experiment, or lists of such arrays for several."""
        us = list(u) if isinstance(u, (list, tuple)) else [u]
        ys = list(y) if isinstance(y, (list, tuple)) else [y]
        if len(us) != len(ys):
            raise ShapeError(f"got {len(us)} input arrays but {len(ys)} output arrays")
        trajs = []
        for i, (ui, yi) in enumerate(zip(us, ys)):
            ua, ya = np.asarray(ui, dtype=np.float64), np.asarray(yi, dtype=np.float64)
            if ua.shape[0] != ya.shape[0]:
                raise ShapeError(
                    f"experiment {i}: u has {ua.shape[0]} samples but y has {ya.shape[0]}"
                )
            trajs.append(Trajectory(u=ua, y=ya))
        n_u, n_y = trajs[0].n_u, trajs[0].n_y
        return cls(
            splits={split: tuple(trajs)},
            dt=dt,
            input_names=tuple(input_names or (f"u{i + 1}" for i in range(n_u))),
            output_names=tuple(output_names or (f"y{i + 1}" for i in range(n_y))),
            metadata=dict(metadata or {"source": "arrays"}),
        )

    # ------------------------------------------------------------------ storage
    def save(self, path: str | os.PathLike[str], *, durable: bool = True) -> Path:
        """Write ``path`` (``.npz``) and its ``.json`` sidecar atomically; return ``path``.
        ``durable=False`` skips the fsyncs (see :mod:`canonid.kernel.io`): for files that a power
        failure may cost, such as generation parts (a damaged part is regenerated)."""
        p = Path(path)
        if p.suffix != ".npz":
            raise DataError(f"dataset path must end in .npz, got {p}")
        arrays: dict[str, np.ndarray] = {}
        infos: dict[str, list[dict[str, Any]]] = {}
        for split, trajs in self.splits.items():
            if "/" in split:
                raise DataError(f"split name must not contain '/': {split!r}")
            infos[split] = []
            for i, tr in enumerate(trajs):
                for key, arr in tr.arrays().items():
                    arrays[f"{split}/{i:05d}/{key}"] = arr
                infos[split].append(dict(tr.info))
        checksum = write_npz(p, arrays, durable=durable)
        header = {
            "format": "canonid-dataset",
            "format_version": FORMAT_VERSION,
            "arrays_file": p.name,
            "checksum_sha256": checksum,
            "dt": self.dt,
            "input_names": list(self.input_names),
            "output_names": list(self.output_names),
            "state_names": None if self.state_names is None else list(self.state_names),
            "counts": self.counts(),
            "trajectory_info": infos,
            "metadata": self.metadata,
        }
        atomic_write_json(p.with_suffix(".json"), header, durable=durable)
        return p

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Dataset:
        """Read a dataset written by :meth:`save` (``path``: the ``.npz``, its ``.json``, or a
        folder holding ``dataset.npz``), validating checksum, shapes and finiteness."""
        p = Path(path)
        if p.is_dir():
            p = p / "dataset.npz"
        if p.suffix == ".json":
            p = p.with_suffix(".npz")
        meta_path = p.with_suffix(".json")
        if not p.exists():
            raise DataError(f"dataset file not found: {p}")
        if not meta_path.exists():
            raise DataError(
                f"dataset {p} has no metadata file {meta_path.name} (incomplete write or not a "
                "canonid dataset)"
            )
        header = read_json(meta_path, what="dataset metadata")
        if not isinstance(header, dict) or header.get("format") != "canonid-dataset":
            raise DataError(f"{meta_path} is not canonid dataset metadata (field 'format')")
        _check_header(header, meta_path)
        actual = sha256_file(p)
        if actual != header["checksum_sha256"]:
            raise DataError(
                f"dataset {p} does not match its checksum in {meta_path.name} "
                f"(expected {header['checksum_sha256'][:12]}…, got {actual[:12]}…): the file is "
                "corrupt, truncated or was modified"
            )
        arrays = read_npz(p, what="dataset")
        stored = {key.rsplit("/", 1)[0] for key in arrays}
        counted = {f"{split}/{i:05d}" for split, n in header["counts"].items() for i in range(n)}
        if stored != counted:
            extra = sorted(stored - counted)
            raise DataError(
                f"dataset {p} holds trajectories {extra[:3]} that {meta_path.name}'s field "
                "'counts' does not count"
                if extra
                else f"dataset {p} lacks trajectories {sorted(counted - stored)[:3]} that "
                f"{meta_path.name}'s field 'counts' counts"
            )
        infos = header.get("trajectory_info") or {}
        splits: dict[str, tuple[Trajectory, ...]] = {}
        for split, count in header["counts"].items():
            trajs = []
            for i in range(int(count)):
                prefix = f"{split}/{i:05d}/"
                fields = {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}
                if "u" not in fields or "y" not in fields:
                    raise DataError(f"dataset {p}: trajectory {prefix[:-1]} lacks 'u' or 'y'")
                unknown = sorted(set(fields) - set(_FIELDS))
                if unknown:
                    raise DataError(
                        f"dataset {p}: trajectory {prefix[:-1]} has unknown arrays {unknown}"
                    )
                info = infos.get(split, [{}] * int(count))[i]
                try:
                    trajs.append(Trajectory(**fields, info=info))
                except ShapeError as exc:
                    raise DataError(f"dataset {p}, {prefix[:-1]}: {exc}") from exc
            splits[split] = tuple(trajs)
        try:
            return cls(
                splits=splits,
                dt=float(header["dt"]),
                input_names=tuple(header["input_names"]),
                output_names=tuple(header["output_names"]),
                state_names=None
                if header.get("state_names") is None
                else tuple(header["state_names"]),
                metadata=header.get("metadata", {}),
            )
        except ShapeError as exc:
            raise DataError(f"dataset {p}: {exc}") from exc
