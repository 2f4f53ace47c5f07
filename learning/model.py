"""A trained model in physical units: network + normalisation; simulate, save, load, export.

Folder layout written by :meth:`Model.save` (a run folder holds these plus training artefacts):

* ``config.json`` — ``{"format": "canonid-model", "format_version", "model": name,
  "net": constructor arguments, "info": free JSON (training options, data description)}``;
* ``weights.pt`` — ``torch.save(state_dict)`` of the network (CPU tensors), read back with
  ``torch.load(..., weights_only=True)``;
* ``normalisation.json`` — :class:`canonid.learning.data.Normalisation` (training statistics).

Simulation convention (:meth:`Model.simulate`): ``u`` holds samples ``0 … T−1``, ``y_burn_in``
the measured outputs of samples ``0 … ℓ−1``; the result holds the open-loop predictions of
samples ``ℓ … T−1`` (``T − ℓ`` rows).
"""

from __future__ import annotations

import io
import math
import os
import pickle
import zipfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from canonid.kernel.catalog import INFO_TRAINING_RANGE, INFO_UNVALIDATED
from canonid.kernel.errors import CanonidError, CheckpointError, DataError, ShapeError
from canonid.kernel.io import (
    atomic_write_bytes,
    atomic_write_json,
    confined,
    guarded,
    is_json_number,
    is_outside_record,
    make_folder,
    read_json,
)
from canonid.learning.data import Normalisation
from canonid.learning.export import NumpyModel, ReducedNumpyModel
from canonid.learning.nets import ALL_NETS, ReducedNet, SequenceModel, build_net
from canonid.learning.rollout import rollout_physical, simulate

__all__ = [
    "MODEL_FORMAT_VERSION",
    "Model",
    "check_architecture",
    "check_info",
    "check_same",
    "load_state",
    "read_weights",
]

MODEL_FORMAT_VERSION = 1
CONFIG_FILE, WEIGHTS_FILE, NORM_FILE = "config.json", "weights.pt", "normalisation.json"
#: the files a saved model consists of
MODEL_FILES = (CONFIG_FILE, WEIGHTS_FILE, NORM_FILE)


def check_same(found: Mapping[str, Any], expected: Mapping[str, Any], *, what: str) -> None:
    """Raise :class:`CheckpointError` naming every key whose value differs."""
    diffs = [
        f"{key}: {found.get(key)!r} there, {value!r} here"
        for key, value in expected.items()
        if found.get(key) != value
    ]
    if diffs:
        raise CheckpointError(f"{what} does not match: " + "; ".join(diffs))


class Model:
    """A network of the registry with the normalisation it was trained under.

    Args:
        net: the network (normalised units).
        norm: training statistics.
        info: JSON-ready facts saved in ``config.json`` (training options, data, ...).
    """

    def __init__(
        self, net: SequenceModel, norm: Normalisation, *, info: Mapping[str, Any] | None = None
    ) -> None:
        if (norm.n_u, norm.n_y) != (net.n_u, net.n_y):
            raise ShapeError(
                f"normalisation is for n_u={norm.n_u}, n_y={norm.n_y}; the network has "
                f"n_u={net.n_u}, n_y={net.n_y}"
            )
        self.net, self.norm, self.info = net, norm, dict(info or {})

    # ------------------------------------------------------------------ description
    @property
    def name(self) -> str:
        return self.net.name

    @property
    def window(self) -> int:
        return self.net.window

    @property
    def n_u(self) -> int:
        return self.net.n_u

    @property
    def n_y(self) -> int:
        return self.net.n_y

    def __repr__(self) -> str:
        return f"Model({self.name!r}, window={self.window}, n_u={self.n_u}, n_y={self.n_y})"

    # ------------------------------------------------------------------ prediction
    def predict(self, u: np.ndarray, y_burn_in: np.ndarray) -> np.ndarray:
        """Batched open-loop predictions, physical units: ``u`` ``(N, T, n_u)`` and ``y_burn_in``
        ``(N, ℓ, n_y)`` → ``(N, T − ℓ, n_y)`` (no validation; see :meth:`simulate`)."""
        return rollout_physical(self.net, self.norm, u, y_burn_in)

    def simulate(self, u: Any, y_burn_in: Any) -> np.ndarray:
        """Open-loop simulation in physical units (see the module docstring).

        ``u`` is ``(T, n_u)`` and ``y_burn_in`` ``(ℓ, n_y)`` → ``(T − ℓ, n_y)``; or batched,
        ``(N, T, n_u)`` and ``(N, ℓ, n_y)`` → ``(N, T − ℓ, n_y)``.
        """
        return simulate(self.net, self.norm, u, y_burn_in)

    def export(self) -> NumpyModel:
        """A plain numpy object for the analysis layer (see :mod:`canonid.learning.export`): a
        ``ReducedNumpyModel`` for a reduced model, else a ``NumpyModel``."""
        if isinstance(self.net, ReducedNet):
            return ReducedNumpyModel(self.net, self.norm)
        return NumpyModel(self.net, self.norm)

    # ------------------------------------------------------------------ storage
    def save(self, folder: str | os.PathLike[str]) -> Path:
        """Write ``config.json``, ``weights.pt`` and ``normalisation.json`` into ``folder``."""
        out = make_folder(folder)
        buf = io.BytesIO()
        torch.save({k: v.detach().cpu() for k, v in self.net.state_dict().items()}, buf)
        atomic_write_bytes(out / WEIGHTS_FILE, buf.getvalue())
        atomic_write_json(out / NORM_FILE, self.norm.to_dict())
        atomic_write_json(
            out / CONFIG_FILE,
            {
                "format": "canonid-model",
                "format_version": MODEL_FORMAT_VERSION,
                "model": self.name,
                "net": self.net.config(),
                "info": self.info,
            },
        )
        return out

    @classmethod
    def load(
        cls,
        folder: str | os.PathLike[str],
        *,
        expect: Mapping[str, Any] | None = None,
        map_location: str | torch.device = "cpu",
    ) -> Model:
        """Read a model written by :meth:`save`.

        ``expect`` (e.g. ``{"model": "mlp", "window": 10}``; keys ``model`` or any network
        argument) is compared with what was saved; every difference is named in a
        :class:`CheckpointError`, as is any weight whose name or shape does not fit.
        """
        folder = Path(folder)
        with confined(folder):  # no link below the folder is followed
            return cls._load(folder, expect=expect, map_location=map_location)

    @classmethod
    def _load(
        cls,
        folder: Path,
        *,
        expect: Mapping[str, Any] | None,
        map_location: str | torch.device,
    ) -> Model:
        if not folder.is_dir():
            raise CheckpointError(f"model folder not found: {folder}")
        if not (folder / CONFIG_FILE).exists():
            raise CheckpointError(
                f"{folder} holds no model: no {CONFIG_FILE} (give a run folder that canonid "
                "train wrote, its --out)"
            )
        config = read_json(folder / CONFIG_FILE, what="model configuration")
        if not isinstance(config, dict) or config.get("format") != "canonid-model":
            raise CheckpointError(f"{folder / CONFIG_FILE} is not a canonid model configuration")
        version = config.get("format_version", MODEL_FORMAT_VERSION)
        if type(version) is not int or version != MODEL_FORMAT_VERSION:
            raise CheckpointError(
                f"{folder / CONFIG_FILE}: field 'format_version' is {version!r}; this canonid "
                f"reads version {MODEL_FORMAT_VERSION} (a newer canonid wrote it, or a hand edit)"
            )
        name, net_config = config.get("model"), config.get("net")
        if not isinstance(name, str) or name not in ALL_NETS or not isinstance(net_config, dict):
            raise CheckpointError(
                f"{folder / CONFIG_FILE}: field 'model' must be one of {sorted(ALL_NETS)} and "
                f"'net' an object; got model={name!r}"
            )
        if expect:
            check_same({"model": name, **net_config}, expect, what=f"saved model in {folder}")
        try:
            norm = Normalisation.from_dict(
                read_json(folder / NORM_FILE, what="normalisation"), where=str(folder / NORM_FILE)
            )
        except DataError as exc:
            raise CheckpointError(str(exc)) from exc
        state = read_weights(folder / WEIGHTS_FILE, map_location=map_location)
        # the architecture is checked against the weights before anything is allocated
        check_architecture(
            name, net_config, state, config=folder / CONFIG_FILE, weights=folder / WEIGHTS_FILE
        )
        net = build_net(name, **net_config)
        load_state(net, state, where=str(folder / WEIGHTS_FILE))
        info = check_info(config.get("info", {}), net, where=folder / CONFIG_FILE)
        return cls(net, norm, info=info)


def check_info(info: Any, net: SequenceModel, *, where: Path) -> dict[str, Any]:
    """The ``info`` field of ``config.json``, its fields that canonid reads checked by type: an
    object; ``dt`` a positive finite number of seconds; ``input_names`` / ``output_names`` lists
    of ``n_u`` / ``n_y`` strings; ``training_range`` an object whose ``inputs`` / ``outputs`` are
    ``n_u`` / ``n_y`` pairs ``[low, high]`` of finite numbers, ``low <= high``;
    ``training_outside_validation`` a list of objects with a string ``name``, a ``kind``
    ``input`` or ``output`` and numbers ``span_low``, ``span_high``, ``share``, ``distance`` and
    ``beyond`` (or null) (each may be absent: models saved without data have none)."""
    if not isinstance(info, Mapping):
        raise CheckpointError(f"{where}: field 'info' must be an object, got {_kind(info)}")
    dt = info.get("dt")
    if dt is not None and not (is_json_number(dt) and 0 < dt < math.inf):
        raise CheckpointError(
            f"{where}: field 'info.dt' must be a positive finite number of seconds, got {dt!r}"
        )
    for key, count in (("input_names", net.n_u), ("output_names", net.n_y)):
        names = info.get(key)
        if names is None:
            continue
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise CheckpointError(
                f"{where}: field 'info.{key}' must be a list of names, got {names!r}"
            )
        if len(names) != count:
            raise CheckpointError(
                f"{where}: field 'info.{key}' names {len(names)} signal(s) {names}; the "
                f"network has {count}"
            )
    _check_spans(info.get(INFO_TRAINING_RANGE), net, where=where)
    _check_outside(info.get(INFO_UNVALIDATED), where=where)
    return dict(info)


def _check_outside(found: Any, *, where: Path) -> None:
    """``info.training_outside_validation``: absent, or a list of the records it names."""
    if found is None:
        return
    if not isinstance(found, list) or not all(map(is_outside_record, found)):
        raise CheckpointError(
            f"{where}: field 'info.{INFO_UNVALIDATED}' must be a list of objects with "
            "name, kind (input or output), span_low, span_high, share, distance and beyond, "
            f"got {found!r}"
        )


def _check_spans(spans: Any, net: SequenceModel, *, where: Path) -> None:
    """``info.training_range``: absent, or ``n_u`` / ``n_y`` finite ``[low, high]`` pairs."""
    if spans is None:
        return
    field = f"info.{INFO_TRAINING_RANGE}"
    if not isinstance(spans, Mapping):
        raise CheckpointError(f"{where}: field '{field}' must be an object, got {_kind(spans)}")
    for key, count in (("inputs", net.n_u), ("outputs", net.n_y)):
        pairs = spans.get(key)
        good = (
            isinstance(pairs, list)
            and len(pairs) == count
            and all(
                isinstance(p, list)
                and len(p) == 2
                and all(is_json_number(v) and math.isfinite(v) for v in p)
                and p[0] <= p[1]
                for p in pairs
            )
        )
        if not good:
            raise CheckpointError(
                f"{where}: field '{field}.{key}' must be {count} pair(s) [low, high] of finite "
                f"numbers, low <= high, got {pairs!r}"
            )


def _kind(value: Any) -> str:
    """The JSON kind of ``value`` for a message (``a string 'abc'``, ``a list``)."""
    names = {str: "a string", list: "a list", dict: "an object", bool: "a boolean"}
    kind = names.get(type(value), "a number" if is_json_number(value) else "null")
    return f"{kind} {value!r}" if isinstance(value, (str, int, float)) else kind


def load_weights(
    net: SequenceModel, path: Path, *, map_location: str | torch.device = "cpu"
) -> None:
    """Load a ``state_dict`` file into ``net`` (``weights_only=True``), naming any mismatch."""
    load_state(net, read_weights(path, map_location=map_location), where=str(path))


def read_weights(path: Path, *, map_location: str | torch.device = "cpu") -> Any:
    """The ``state_dict`` saved in ``path``, read with ``weights_only=True`` (tensors, never
    Python objects); a file that is missing, corrupt or holds NaN raises CheckpointError."""
    if not guarded(path).is_file():
        raise CheckpointError(f"weights file not found: {path}")
    if not zipfile.is_zipfile(path):  # torch.save writes a zip archive
        raise CheckpointError(
            f"cannot read weights {path}: not a torch file (corrupt or truncated)"
        )
    try:
        state = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as exc:  # torch's advice to unpickle is wrong for user files
        raise CheckpointError(
            f"cannot read weights {path}: it holds Python objects besides tensors, which canonid "
            "never unpickles (a file not written by canonid, or tampered with)"
        ) from exc
    except Exception as exc:  # torch raises several types for corrupt files
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CheckpointError(
            f"cannot read weights {path}: corrupt or truncated ({first})"
        ) from exc
    if isinstance(state, Mapping):
        bad = [
            k
            for k, v in state.items()
            if isinstance(v, torch.Tensor)
            and v.is_floating_point()
            and not bool(v.isfinite().all())
        ]
        if bad:
            raise CheckpointError(
                f"weights {path}: tensor(s) {bad[:3]} hold NaN or infinite values (a diverged "
                "or damaged model)"
            )
    return state


def check_architecture(
    name: str, net_config: Mapping[str, Any], state: Any, *, config: Path, weights: Path
) -> None:
    """Refuse, before any network is built for real, a recorded architecture (``config.json``
    field ``net``) that the weights do not hold.

    Two steps, neither of which allocates what the configuration asks for: every size in
    ``net`` is bounded by the weights (a list of layers by the number of tensors, a width by the
    number of values: no layer is wider than all the weights together), so that even the
    skeleton below stays as small as the file; then the network is built on the ``meta`` device
    (shapes without memory) and its tensor names and shapes are compared with the weights'.
    """
    if not isinstance(state, Mapping):
        raise CheckpointError(f"{weights}: expected a state_dict, got {type(state).__name__}")
    tensors = [v for v in state.values() if isinstance(v, torch.Tensor)]
    n_tensors, n_values = len(tensors), sum(v.numel() for v in tensors)
    held = f"the weights in {weights} hold"
    for field, value in _fields(net_config, "net"):
        if isinstance(value, (list, tuple)) and len(value) > n_tensors:
            raise CheckpointError(
                f"{config}: field {field!r} lists {len(value)} layers; {held} only "
                f"{n_tensors} tensors"
            )
        if field.endswith(".num_layers") and isinstance(value, int) and value > n_tensors:
            raise CheckpointError(
                f"{config}: field {field!r} = {value}: {held} only {n_tensors} tensors"
            )
        # the window of a recurrent model sizes no tensor (only the burn-in it reads)
        if _is_int(value) and not field.endswith(".window") and value > n_values:
            raise CheckpointError(
                f"{config}: field {field!r} = {value} is larger than the {n_values} numbers {held}"
            )
    try:
        with torch.device("meta"):
            skeleton = build_net(name, **net_config)
    except (CanonidError, RuntimeError, OverflowError) as exc:  # torch: a negative size, say
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CheckpointError(f"{config}: field 'net' describes no network: {first}") from exc
    problems = _mismatch(skeleton.state_dict(), state, theirs=weights.name, ours=config.name)
    if problems:
        raise CheckpointError(
            f"{config}: field 'net' ({name!r}, window {skeleton.window}, n_u={skeleton.n_u}, "
            f"n_y={skeleton.n_y}) is not the network whose weights are in {weights} (weights do "
            f"not fit: {problems})"
        )


def _fields(value: Any, path: str) -> Iterator[tuple[str, Any]]:
    """Every value in a JSON tree with its path (``net.hidden``, ``net.hidden[0]``)."""
    yield path, value
    if isinstance(value, Mapping):
        for key, item in value.items():
            yield from _fields(item, f"{path}.{key}")
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            yield from _fields(item, f"{path}[{i}]")


def _shape(value: Any) -> str:
    return str(tuple(value.shape)) if isinstance(value, torch.Tensor) else "(not a tensor)"


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _mismatch(
    own: Mapping[str, torch.Tensor], state: Mapping[str, Any], *, theirs: str, ours: str
) -> str:
    """What keeps ``state`` (from ``theirs``) from loading into a network whose ``state_dict``
    is ``own`` (from ``ours``): missing, unexpected and mis-shaped tensors, or ``""``."""
    missing = sorted(set(own) - set(state))
    extra = sorted(set(state) - set(own))
    shapes = [
        f"{k} {_shape(state[k])} in {theirs} vs {tuple(own[k].shape)} in {ours}"
        for k in sorted(set(own) & set(state))
        if not isinstance(state[k], torch.Tensor) or state[k].shape != own[k].shape
    ]
    parts = []
    if missing:
        parts.append(f"missing {missing}")
    if extra:
        parts.append(f"unexpected {extra}")
    if shapes:
        parts.append("shape differs: " + ", ".join(shapes))
    return "; ".join(parts)


def load_state(net: SequenceModel, state: Any, *, where: str) -> None:
    """``net.load_state_dict(state)``, strict, with a :class:`CheckpointError` that names the
    missing, unexpected and mis-shaped tensors."""
    if not isinstance(state, Mapping):
        raise CheckpointError(f"{where}: expected a state_dict, got {type(state).__name__}")
    problems = _mismatch(net.state_dict(), state, theirs="the weights", ours="the model")
    if problems:
        raise CheckpointError(
            f"{where}: weights do not fit model {net.name!r} (window {net.window}, "
            f"n_u={net.n_u}, n_y={net.n_y}): {problems}"
        )
    net.load_state_dict(state)
