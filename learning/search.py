"""How canonid chooses its default model: successive halving over a declared candidate table.

The method is successive halving (Jamieson & Talwalkar, "Non-stochastic best arm identification
and hyperparameter optimization", AISTATS 2016), one bracket of Hyperband (Li et al., JMLR 18,
2018). Every candidate of the table trains for the first rung's budget; the best ⌊n/η⌋ of the
``n`` candidates of a rung (at least one) go on to the next rung, whose budget is η times
larger, until one is left, trained to the full budget: with ``R`` rungs, rung ``r = 0 … R−1``
trains to ``epochs · η^(r−R+1)`` epochs (rounded up).

* **Rungs are prefixes of one run.** Every candidate trains with the schedule of the full budget
  (learning rate, curriculum, early stopping); a rung pauses it (``fit(until=…)``) and a
  promoted candidate continues from its checkpoint. The chosen model's run is therefore exactly
  the run it would have been alone, and a killed search resumes to the same bytes.
* **Ranked as the field scores.** Every candidate validates on the free-run simulation of each
  validation record (``TrainOptions.val_measure = "simulation"``), scored from the same sample
  for all of them: the table's largest window (``val_n_init``). The rank is the best validation
  loss so far (the model that candidate would keep); one whose simulation is not finite ranks
  last and is never promoted, never kept.
* **The only constants** are the halving rate :data:`ETA` and the table's axes
  (:data:`WINDOWS`, :data:`CUBIC_UNITS`); a user's ``--window`` / ``--cubic`` / ``--hidden``
  fixes that axis.

:class:`Search` is the record of a search (``search.json`` in a run folder); it holds validation
losses only. :func:`successive_halving` is the procedure, independent of what a candidate is
(tested on synthetic candidates whose ranks are known); :func:`search` runs it for the
output-error models of :func:`canonid.learning.training.fit`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.kernel.errors import CheckpointError, OptionError
from canonid.kernel.io import atomic_write_json, confined, make_folder, read_json

if TYPE_CHECKING:
    from canonid.learning.training import FitResult

__all__ = [
    "CUBIC_UNITS",
    "ETA",
    "SEARCH_DIR",
    "SEARCH_FILE",
    "WINDOWS",
    "Candidate",
    "Search",
    "SearchRow",
    "adopt",
    "candidate_table",
    "cubic_axis",
    "fitting_windows",
    "rung_budgets",
    "search",
    "successive_halving",
]

#: the halving rate η: each rung keeps the best ⌊n/η⌋ and trains them η times longer
ETA = 3
#: the windows ℓ of the table (those the data allow): a doubling ladder long enough for the
#: slowest modes of lightly damped systems; shorter ones with ``--window L``
WINDOWS = (10, 20, 40, 80)
#: Ours (MLP)'s cubic branch: none, or this many units (the branch extrapolates beyond the
#: training amplitude where the system's nonlinearity grows like a polynomial)
CUBIC_UNITS = (0, 16)
#: the search's record in a run folder, and the folder of its candidates' runs
SEARCH_FILE = "search.json"
SEARCH_DIR = "search"
_FORMAT = "canonid-search"


@dataclass(frozen=True)
class Candidate:
    """One point of the table: window ℓ, cubic units, hidden widths (``None``: the model's)."""

    window: int
    cubic: int = 0
    hidden: tuple[int, ...] | None = None

    @property
    def name(self) -> str:
        """``l10``, ``l10-c16``, ``l10-h64x64``: the candidate's folder in ``RUN/search``."""
        parts = [f"l{self.window}"]
        if self.cubic:
            parts.append(f"c{self.cubic}")
        if self.hidden is not None:
            parts.append("h" + "x".join(map(str, self.hidden)))
        return "-".join(parts)

    def net_options(
        self, base: Mapping[str, Any], hidden_option: str | None = "hidden"
    ) -> dict[str, Any]:
        """``base`` with this candidate's network options (``hidden_option``: the model's
        constructor argument for the widths)."""
        options = dict(base)
        if self.cubic or "cubic" in base:
            options["cubic"] = self.cubic
        if self.hidden is not None:
            if hidden_option is None:
                raise OptionError("this model's layer sizes follow from the window: no widths")
            options[hidden_option] = list(self.hidden)
        return options

    def to_dict(self) -> dict[str, Any]:
        return {
            "window": self.window,
            "cubic": self.cubic,
            "hidden": None if self.hidden is None else list(self.hidden),
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> Candidate:
        try:
            hidden = data["hidden"]
            return cls(
                window=_count(data["window"]),
                cubic=_count(data["cubic"], zero=True),
                hidden=None if hidden is None else tuple(_count(h) for h in hidden),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{where}: a candidate is unreadable ({exc})") from None


def _count(value: Any, *, zero: bool = False) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < (0 if zero else 1):
        raise ValueError(f"{value!r} is not a count")
    return value


def cubic_axis(cubic: Any) -> tuple[int, ...]:
    """The cubic axis that a network's ``cubic`` option asks for: ``"auto"`` searches
    :data:`CUBIC_UNITS`, a number fixes it, none (a model without the branch) is ``(0,)``."""
    if cubic == "auto":
        return CUBIC_UNITS
    return (cubic,) if isinstance(cubic, int) and not isinstance(cubic, bool) else (0,)


def candidate_table(
    windows: Sequence[int] = WINDOWS,
    cubic: Sequence[int] = CUBIC_UNITS,
    hidden: Sequence[tuple[int, ...] | None] = (None,),
) -> tuple[Candidate, ...]:
    """Every combination of the axes, in table order (windows first, then cubic, then widths)."""
    if not windows or not cubic or not hidden:
        raise OptionError("the candidate table has an empty axis")
    return tuple(Candidate(w, c, h) for w in windows for c in cubic for h in hidden)


def fitting_windows(
    train: Sequence[Any], val: Sequence[Any], windows: Sequence[int], horizon: int
) -> list[int]:
    """The ``windows`` that the records allow: every record holds ℓ + 1 samples, the longest
    training record the training rollout ``horizon`` after ℓ, and the longest validation record
    twice ℓ, so that at least half of it is simulated after the burn-in."""
    shortest = min(len(t.y) for t in [*train, *val])
    longest_train, longest_val = max(len(t.y) for t in train), max(len(t.y) for t in val)
    return [
        int(ell)
        for ell in windows
        if shortest >= ell + 1 and longest_train >= ell + horizon and longest_val >= 2 * ell
    ]


def rung_budgets(candidates: int, epochs: int, eta: int = ETA) -> list[tuple[int, int]]:
    """``(candidates, epochs)`` of each rung: ``n, ⌊n/η⌋, …`` (at least one) down to one, the
    last rung at ``epochs`` and each earlier one η times shorter (at least one epoch)."""
    if candidates < 1 or epochs < 1 or eta < 2:
        raise OptionError(
            f"a search needs candidates ≥ 1, epochs ≥ 1, η ≥ 2; got {candidates}, {epochs}, {eta}"
        )
    counts = [candidates]
    while counts[-1] > 1:
        counts.append(max(1, counts[-1] // eta))
    last = len(counts) - 1
    return [(n, max(1, math.ceil(epochs / eta ** (last - r)))) for r, n in enumerate(counts)]


@dataclass(frozen=True)
class SearchRow:
    """One candidate trained to one rung's budget (validation losses normalised)."""

    candidate: Candidate
    rung: int
    budget: int
    best_val_loss: float
    best_epoch: int
    epochs_run: int
    stopped: str
    cpu_seconds: float = 0.0

    @property
    def finite(self) -> bool:
        return math.isfinite(self.best_val_loss)

    def to_dict(self) -> dict[str, Any]:
        return {
            "candidate": self.candidate.to_dict(),
            "rung": self.rung,
            "budget": self.budget,
            "best_val_loss": self.best_val_loss if self.finite else None,
            "best_epoch": self.best_epoch,
            "epochs_run": self.epochs_run,
            "stopped": self.stopped,
            "cpu_seconds": round(self.cpu_seconds, 3),
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> SearchRow:
        try:
            loss = data["best_val_loss"]
            return cls(
                candidate=Candidate.from_dict(data["candidate"], where=where),
                rung=_count(data["rung"], zero=True),
                budget=_count(data["budget"]),
                best_val_loss=math.inf if loss is None else float(loss),
                best_epoch=_count(data["best_epoch"], zero=True),
                epochs_run=_count(data["epochs_run"], zero=True),
                stopped=str(data["stopped"]),
                cpu_seconds=float(data["cpu_seconds"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{where}: a row is unreadable ({exc})") from None


def _rank_key(row: SearchRow, order: Mapping[Candidate, int]) -> tuple[float, int]:
    """Lower is better: the loss (non-finite last), then the table's order."""
    return (row.best_val_loss if row.finite else math.inf, order[row.candidate])


@dataclass(frozen=True)
class Search:
    """A search's plan and the rows trained so far; :attr:`chosen` once it is complete."""

    candidates: tuple[Candidate, ...]
    epochs: int
    eta: int = ETA
    val_n_init: int | None = None
    rows: tuple[SearchRow, ...] = field(default=())

    @property
    def budgets(self) -> list[tuple[int, int]]:
        return rung_budgets(len(self.candidates), self.epochs, self.eta)

    def rung_rows(self, rung: int) -> list[SearchRow]:
        return [r for r in self.rows if r.rung == rung]

    def entrants(self, rung: int) -> list[Candidate]:
        """The candidates of ``rung``: the table, then the best ⌊n/η⌋ finite ones of the rung
        before (none when that rung is not complete or held no finite loss)."""
        if rung == 0:
            return list(self.candidates)
        before = self.entrants(rung - 1)
        rows = {r.candidate: r for r in self.rung_rows(rung - 1)}
        if any(c not in rows for c in before):
            return []
        order = {c: i for i, c in enumerate(self.candidates)}
        ranked = sorted((rows[c] for c in before), key=lambda r: _rank_key(r, order))
        keep = self.budgets[rung][0]
        return [r.candidate for r in ranked[:keep] if r.finite]

    @property
    def complete(self) -> bool:
        last = len(self.budgets) - 1
        entrants = self.entrants(last)
        done = {r.candidate for r in self.rung_rows(last)}
        return bool(entrants) and all(c in done for c in entrants)

    @property
    def chosen(self) -> Candidate | None:
        """The candidate the search keeps: the best finite one of the last rung."""
        if not self.complete:
            return None
        last = len(self.budgets) - 1
        order = {c: i for i, c in enumerate(self.candidates)}
        rows = [r for r in self.rung_rows(last) if r.finite]
        return min(rows, key=lambda r: _rank_key(r, order)).candidate if rows else None

    @property
    def cpu_seconds(self) -> float:
        return sum(r.cpu_seconds for r in self.rows)

    def with_row(self, row: SearchRow) -> Search:
        kept = [r for r in self.rows if (r.candidate, r.rung) != (row.candidate, row.rung)]
        return dataclasses.replace(self, rows=(*kept, row))

    def table(self) -> str:
        """The candidates and their validation losses per rung (what ``canonid train``
        prints); ``-``: not trained at that rung, ``inf``: its simulation was not finite."""
        budgets = self.budgets
        head = ["candidate", *(f"rung {r} ({e} ep.)" for r, (_, e) in enumerate(budgets))]
        cells = {(r.candidate, r.rung): r for r in self.rows}
        lines = [" | ".join(head)]
        chosen = self.chosen
        for cand in self.candidates:
            row = [cand.name + (" *" if cand == chosen else "")]
            for rung in range(len(budgets)):
                done = cells.get((cand, rung))
                row.append("-" if done is None else _loss(done))
            lines.append(" | ".join(row))
        return "\n".join(lines)

    def summary(self) -> str:
        chosen = self.chosen
        n, rungs = len(self.candidates), len(self.budgets)
        if chosen is None:
            return f"search: {n} candidates over {rungs} rungs, not complete"
        return (
            f"search: {n} candidates, {rungs} rungs of successive halving (η = {self.eta}), "
            f"ranked on the free-run simulation of the validation records; chosen {chosen.name} "
            f"(--window / --cubic / --hidden fix an axis)"
        )

    def line(self) -> str:
        """One line for a record: each candidate's validation loss at its last rung, the
        choice."""
        last: dict[Candidate, SearchRow] = {}
        for row in sorted(self.rows, key=lambda r: r.rung):
            last[row.candidate] = row
        losses = "; ".join(
            f"{c.name} {_loss(last[c])} (rung {last[c].rung})" for c in self.candidates if c in last
        )
        chosen = "none" if self.chosen is None else self.chosen.name
        return (
            f"the search (successive halving, η = {self.eta}, {len(self.budgets)} rungs up to "
            f"{self.epochs} epochs; validation simulation MSE, normalised: {losses}) chose "
            f"{chosen}, {self.cpu_seconds:.0f} CPU s"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": _FORMAT,
            "method": "successive halving (Jamieson & Talwalkar 2016)",
            "measure": "free-run simulation MSE of the validation records (normalised)",
            "eta": self.eta,
            "epochs": self.epochs,
            "val_n_init": self.val_n_init,
            "candidates": [c.to_dict() for c in self.candidates],
            "rows": [r.to_dict() for r in self.rows],
            "chosen": None if self.chosen is None else self.chosen.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Any, *, where: str) -> Search:
        if not isinstance(data, Mapping) or data.get("format") != _FORMAT:
            raise CheckpointError(f"{where}: not a search record of canonid")
        try:
            n_init = data["val_n_init"]
            return cls(
                candidates=tuple(Candidate.from_dict(c, where=where) for c in data["candidates"]),
                epochs=_count(data["epochs"]),
                eta=_count(data["eta"]),
                val_n_init=None if n_init is None else _count(n_init),
                rows=tuple(SearchRow.from_dict(r, where=where) for r in data["rows"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{where}: unreadable search record ({exc})") from None

    @classmethod
    def read(cls, run_dir: Path) -> Search:
        path = Path(run_dir) / SEARCH_FILE
        return cls.from_dict(read_json(path), where=str(path))

    def write(self, run_dir: Path) -> None:
        atomic_write_json(Path(run_dir) / SEARCH_FILE, self.to_dict())


def _loss(row: SearchRow) -> str:
    return f"{row.best_val_loss:.4g}" if row.finite else "inf"


#: trains one candidate to ``until`` epochs (continuing its earlier rungs) and returns its row
Trainer = Callable[[Candidate, int, int], SearchRow]


def successive_halving(
    plan: Search,
    train: Trainer,
    *,
    record: Callable[[Search], None] | None = None,
    run_rung: Callable[[Trainer, list[tuple[Candidate, int, int]]], list[SearchRow]] | None = None,
) -> Search:
    """Run (or continue) the search ``plan``: rung by rung, train every entrant without a row
    (``train(candidate, rung, until)``; ``run_rung`` trains one rung's list, default one after
    the other) and call ``record`` with the search after each rung. Raises
    :class:`~canonid.kernel.errors.OptionError` when every candidate of a rung failed to
    simulate (no model can be kept)."""
    search = plan
    for rung, (_, until) in enumerate(search.budgets):
        entrants = search.entrants(rung)
        if not entrants:
            raise OptionError(
                "search: no candidate's validation simulation stayed finite at rung "
                f"{rung}; every one diverged (lower the learning rate or the window)"
            )
        done = {r.candidate for r in search.rung_rows(rung)}
        todo = [(c, rung, until) for c in entrants if c not in done]
        rows = run_rung(train, todo) if run_rung is not None else [train(*job) for job in todo]
        for row in rows:
            search = search.with_row(row)
        if record is not None and todo:
            record(search)
    if search.chosen is None:
        raise OptionError("search: no candidate's validation simulation stayed finite")
    return search


def _as_row(candidate: Candidate, rung: int, until: int, fitted: Any, cpu: float) -> SearchRow:
    return SearchRow(
        candidate=candidate,
        rung=rung,
        budget=until,
        best_val_loss=float(fitted.best_val_loss),
        best_epoch=int(fitted.best_epoch),
        epochs_run=int(fitted.epochs_run),
        stopped=str(fitted.stopped),
        cpu_seconds=cpu,
    )


@dataclass(frozen=True)
class CandidateTrainer:
    """Trains a candidate of :func:`search` in ``folder/<name>`` with :func:`fit` (a picklable
    callable, for worker processes)."""

    train: tuple[Trajectory, ...]
    val: tuple[Trajectory, ...]
    model: str
    options: Any
    net_options: Mapping[str, Any]
    folder: Path
    info: Mapping[str, Any] | None = None

    def __call__(self, candidate: Candidate, rung: int, until: int) -> SearchRow:
        where = self.folder / candidate.name
        start = time.process_time()
        with confined(self.folder.parent):  # in a worker too: no link below the run followed
            make_folder(where)
            fitted = self._fit(candidate, where, until)
        return _as_row(candidate, rung, until, fitted, time.process_time() - start)

    def _fit(self, candidate: Candidate, where: Path, until: int) -> FitResult:
        from canonid.learning.nets import NETS
        from canonid.learning.training import CHECKPOINT_FILE, fit

        return fit(
            self.train,
            self.val,
            model=self.model,
            window=candidate.window,
            options=self.options,
            net_options=candidate.net_options(self.net_options, NETS[self.model].hidden_option),
            run_dir=where,
            info=self.info,
            resume=(where / CHECKPOINT_FILE).is_file(),
            until=until,
        )


def executor_rung(
    executor: Executor | None,
) -> Callable[[Trainer, list[tuple[Candidate, int, int]]], list[SearchRow]]:
    """A ``run_rung`` for :func:`successive_halving` that trains a rung's candidates side by
    side on ``executor`` (in order here without one)."""

    def run(train: Trainer, jobs: list[tuple[Candidate, int, int]]) -> list[SearchRow]:
        if executor is None or len(jobs) < 2:
            return [train(*job) for job in jobs]
        futures = [executor.submit(train, *job) for job in jobs]
        return [f.result() for f in futures]

    return run


def search(
    train: Sequence[Trajectory],
    val: Sequence[Trajectory],
    *,
    model: str,
    table: Sequence[Candidate],
    options: Any,
    net_options: Mapping[str, Any] | None = None,
    run_dir: str | Path | None = None,
    executor: Executor | None = None,
    eta: int = ETA,
    record: Callable[[Search], None] | None = None,
    info: Mapping[str, Any] | None = None,
) -> tuple[Search, FitResult, Path | None]:
    """Choose among ``table`` by successive halving (see the module docstring) for the
    output-error model ``model``: each candidate trains by :func:`~canonid.learning.training.fit`
    in ``run_dir/search/<name>`` (continued where it is there: the search resumes), validated on
    the free-run simulation of ``val`` from the table's largest window on. Returns the search,
    the chosen candidate's fit and its folder (``None`` without ``run_dir``: the candidates then
    train in a temporary folder, removed at the end)."""
    from canonid.learning.presets import net_options as preset_net_options
    from canonid.learning.training import stored_fit

    train = tuple(as_trajectories(train, what="training data"))
    val = tuple(as_trajectories(val, what="validation data"))
    if not table:
        raise OptionError("search: the candidate table is empty")
    n_init = max(c.window for c in table)
    opts = dataclasses.replace(options, val_measure="simulation", val_n_init=n_init)
    plan = Search(tuple(table), opts.epochs, eta, n_init)
    with _folder(run_dir) as base:
        path = base / SEARCH_FILE
        if path.is_file():
            recorded = Search.read(base)
            if (recorded.candidates, recorded.epochs, recorded.eta, recorded.val_n_init) != (
                plan.candidates,
                plan.epochs,
                plan.eta,
                plan.val_n_init,
            ):
                raise CheckpointError(
                    f"{path} records another search (its candidates or budget differ); give the "
                    "same options to continue it, or another folder"
                )
            plan = recorded
        else:  # recorded before any candidate trains: a killed search resumes from the start
            plan.write(base)

        def written(done: Search) -> None:
            done.write(base)
            if record is not None:
                record(done)

        trainer = CandidateTrainer(
            train,
            val,
            model,
            opts,
            preset_net_options(model, net_options),
            base / SEARCH_DIR,
            None if info is None else dict(info),
        )
        done = successive_halving(plan, trainer, record=written, run_rung=executor_rung(executor))
        chosen = done.chosen
        assert chosen is not None
        last = next(r for r in done.rung_rows(len(done.budgets) - 1) if r.candidate == chosen)
        folder = base / SEARCH_DIR / chosen.name
        fitted = dataclasses.replace(
            stored_fit(folder, stopped=last.stopped),
            search=done,
            cpu_elsewhere=done.cpu_seconds,
        )
        return done, fitted, folder if run_dir is not None else None


def adopt(folder: Path, run_dir: Path) -> None:
    """Copy the chosen candidate's model and checkpoint from ``folder`` into ``run_dir`` (each
    file replaced atomically, the checkpoint first: a resumed run continues the chosen one)."""
    from canonid.kernel.io import atomic_copy
    from canonid.learning.model import MODEL_FILES
    from canonid.learning.training import CHECKPOINT_FILE

    for name in (CHECKPOINT_FILE, *MODEL_FILES):
        atomic_copy(Path(folder) / name, Path(run_dir) / name)


@contextlib.contextmanager
def _folder(run_dir: str | Path | None) -> Iterator[Path]:
    """``run_dir`` as a path (made when missing), or a temporary folder removed on exit when it
    is ``None``."""
    if run_dir is not None:
        yield make_folder(run_dir)
        return
    with tempfile.TemporaryDirectory(prefix="canonid-search-") as tmp:
        yield Path(tmp)
