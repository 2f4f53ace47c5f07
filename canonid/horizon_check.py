"""The training horizon chosen by the input response, for closed-loop data with an excitation.

Output-error rollouts of H samples on data recorded in closed loop can be fitted by a network that
reads the state from the recorded inputs — the controller's answer to the true state — instead of
predicting it from its window; the longer the rollouts, the more that pays (an integrating plant
carries the window's state error along them), and validation rollouts from the same loop reward it
too. Such a model's input response is wrong and a controller built on it fails, while its
validation loss is low. The k-step residuals against the excitation that was added to the
commands tell the models apart on validation data alone (:mod:`canonid.residual_check`).

So ``canonid train``, on a ``canonid generate`` dataset recorded in closed loop whose flights
carry an excitation, for a network trained on rollouts whose horizon the user did not set
(:func:`applies`), after the run's own training (:func:`choose_horizon`):

1. checks the run's model: the correlations of its k-step residuals (k = :data:`CHECK_K`) with
   the excitation outside the :data:`~canonid.residual_check.CONFIDENCE` band, on the validation
   split;
2. when more lie outside than chance allows (:func:`chance_limit`: the binomial count of the
   null at the band's confidence), trains the same request with the shorter rollouts of
   :data:`ALTERNATIVES` in turn, each in ``RUN/horizon-H`` (its own search), and checks
   each; the first whose count chance allows ends the ladder (the longest rollouts that do not
   read the state from the feedback fit best);
3. keeps the model with the fewest correlations outside the band, the longer rollouts on a tie
   (the run's own first). An alternative kept becomes the run folder's (its files copied into
   ``RUN``, so ``evaluate``, ``analyze``, ``export`` and ``--resume`` read it); the run's own
   files move to ``RUN/horizon-H`` (H its horizon) first.

Where an alternative was kept and ``--members`` was not given, the run then trains
:data:`MEMBERS` members of the kept recipe (:mod:`canonid.members`), each candidate held to the
kept model's input response (:func:`response_count`): a single network trained on short rollouts
can still stray where NMPC on it leaves the training data, and the mean of members that answer
the excitation as well as it does smooths that.

``RUN/horizon-check.json`` (:class:`HorizonChoice`) records every check and the choice; a resumed
run that has it decides nothing again. Every count is an estimate (sample correlations against an
asymptotic band).
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from canonid.kernel.errors import CheckpointError, DataError
from canonid.kernel.io import (
    atomic_copy,
    atomic_copy_tree,
    atomic_write_json,
    guarded,
    make_folder,
    read_json,
    run_path,
)

__all__ = [
    "ALTERNATIVES",
    "CHECK_K",
    "HORIZON_CHECK_FILE",
    "MEMBERS",
    "HorizonCandidate",
    "HorizonChoice",
    "applies",
    "chance_limit",
    "choose_horizon",
    "finish_adoption",
    "horizon_dir",
    "response_count",
]

#: the alternatives' training rollouts, tried in this order after the profile's 50: 20, the
#: NMPC's horizon, first, then 10
ALTERNATIVES = (20, 10)
#: the residuals' horizon whose correlations decide (the residual check's default K)
CHECK_K = 10
#: the choice in a run folder
HORIZON_CHECK_FILE = "horizon-check.json"
HORIZON_FORMAT = "canonid-horizon-check"
#: members trained where the check kept an alternative and ``--members`` was not given (module
#: docstring; chosen on the loops of five drone datasets' validation references)
MEMBERS = 3
#: the controllers of ``canonid generate`` that do not feed back (their flights are open loop)
OPEN_LOOP_CONTROLLERS = frozenset({"feedforward"})


def horizon_dir(run_dir: Path, horizon: int) -> Path:
    """``RUN/horizon-H``: a run of the check trained (or moved aside) with rollouts of H."""
    return run_dir / f"horizon-{horizon}"


def chance_limit(tests: int, confidence: float) -> int:
    """The most correlations outside a band of ``confidence`` that chance allows among
    ``tests``: the smallest c with P(X ≤ c) ≥ ``confidence`` for X ~ Binomial(tests, 1 −
    confidence) (the correlations taken as independent; an estimate)."""
    p = 1.0 - confidence
    total = 0.0
    for c in range(tests + 1):
        total += math.comb(tests, c) * p**c * (1.0 - p) ** (tests - c)
        if total >= confidence:
            return c
    return tests


@dataclass(frozen=True)
class HorizonCandidate:
    """One model of the check.

    Attributes:
        horizon: its training rollouts' length.
        folder: where its run is (relative to the run folder; ``"."``: the run folder).
        window: its ℓ.
        outside, tests: correlations outside the band at k = :data:`CHECK_K`, of all.
        largest: the largest ``|r| / band`` among them.
        best_val_loss: its best validation loss (normalised), for the record.
    """

    horizon: int
    folder: str
    window: int
    outside: int
    tests: int
    largest: float
    best_val_loss: float | None


@dataclass(frozen=True)
class HorizonChoice:
    """What :func:`choose_horizon` decided: the candidates checked and the one kept.

    Attributes:
        candidates: the run's own model first, then the alternatives trained, in the ladder's
            order.
        limit: the most correlations outside the band that chance allows (:func:`chance_limit`).
        chosen: the horizon of the kept model.
        state: ``"decided"``, or ``"adopting"`` while the kept alternative's files are copied in
            (a resumed run finishes the copy).
        k, confidence: the check's horizon and band.
        kind: every count is an ``"estimate"``.
    """

    candidates: tuple[HorizonCandidate, ...]
    limit: int
    chosen: int
    state: Literal["decided", "adopting"] = "decided"
    k: int = CHECK_K
    confidence: float = 0.99
    kind: Literal["estimate"] = "estimate"
    checked: str = field(default="residuals against the excitation, validation split")

    @property
    def own(self) -> HorizonCandidate:
        return self.candidates[0]

    @property
    def adopted(self) -> bool:
        """Whether the run folder's model is an alternative."""
        return self.chosen != self.own.horizon

    @property
    def kept(self) -> HorizonCandidate:
        """The kept candidate."""
        return next(c for c in self.candidates if c.horizon == self.chosen)

    def summary(self) -> str:
        """The choice in one line (what ``canonid train`` prints)."""
        own = self.own
        head = (
            f"input response (k = {self.k}-step residuals against the excitation, validation): "
            f"{own.outside} of {own.tests} correlations outside the {self.confidence:.0%} band "
            f"with rollouts of H = {own.horizon}"
        )
        if len(self.candidates) == 1:
            return f"{head}, within the {self.limit} chance allows: H = {own.horizon} kept"
        others = "; ".join(
            f"with H = {c.horizon} (ℓ = {c.window}): {c.outside} of {c.tests}"
            for c in self.candidates[1:]
        )
        kept = self.kept
        verdict = (
            f"H = {kept.horizon} kept (its files in {kept.folder}; the H = {own.horizon} run's in "
            f"horizon-{own.horizon})"
            if self.adopted
            else f"H = {own.horizon} kept (the others in their horizon-H folders)"
        )
        return (
            f"{head}, more than the {self.limit} chance allows (closed-loop data: long rollouts "
            f"can read the state from the feedback); {others}; {verdict}; --train-horizon H "
            "decides instead"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": HORIZON_FORMAT,
            "version": 2,
            "criterion": "the fewest k-step residual correlations with the excitation outside the "
            "band (the longer rollouts on a tie); shorter rollouts are trained in turn only while "
            "every model so far has more than chance allows",
            "checked": self.checked,
            "kind": self.kind,
            "k": self.k,
            "confidence": self.confidence,
            "limit": self.limit,
            "chosen": self.chosen,
            "state": self.state,
            "candidates": [c.__dict__ for c in self.candidates],
        }

    @classmethod
    def read(cls, run_dir: Path) -> HorizonChoice:
        path = run_dir / HORIZON_CHECK_FILE
        data = read_json(path, what="horizon check")
        if not isinstance(data, Mapping) or data.get("format") != HORIZON_FORMAT:
            raise CheckpointError(f"{path} is not a canonid horizon check")
        try:
            for i, c in enumerate(data["candidates"]):  # each folder inside the run, no link
                run_path(run_dir, c["folder"], where=f"{path}: candidates[{i}].folder")
            return cls(
                tuple(HorizonCandidate(**c) for c in data["candidates"]),
                int(data["limit"]),
                int(data["chosen"]),
                data["state"],
                int(data["k"]),
                float(data["confidence"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointError(f"{path} is not a readable horizon check ({exc})") from exc

    def write(self, run_dir: Path) -> None:
        atomic_write_json(run_dir / HORIZON_CHECK_FILE, self.to_dict())


def applies(run_dir: Path, horizon_given: bool) -> bool:
    """Whether the check runs on the run in ``run_dir``: a network trained on rollouts whose
    horizon the user did not give (``horizon_given``), on a ``canonid generate`` dataset recorded
    in closed loop whose flights carry an excitation, or a run that recorded the check."""
    from canonid.kernel.dataset import Dataset
    from canonid.profiles import train_options
    from canonid.residual_check import generated_excitation
    from canonid.runfolder import RunRecipe

    if (run_dir / HORIZON_CHECK_FILE).is_file():
        return True
    recipe = RunRecipe.read(run_dir)
    if horizon_given or "horizon" in recipe.given_options:
        return False  # the user's choice, this time or when the run began
    if recipe.model == "arx" or recipe.val is not None:
        return False  # a validation file of the user's: not the flights the excitation is of
    if recipe.options().horizon != train_options(recipe.profile).horizon:
        return False  # set by the user in a recipe of an older canonid (no given_options)
    path = Path(recipe.data)
    if path.suffix != ".npz" and not (path / "dataset.json").is_file():
        return False  # a CSV: no recorded excitation
    try:
        dataset = Dataset.load(path)
        meta = dataset.metadata
        if meta.get("source") != "canonid generate" or not dataset.splits.get("val"):
            return False
        if (meta.get("controller") or {}).get("type") in OPEN_LOOP_CONTROLLERS:
            return False
        return generated_excitation(dataset, "val") is not None  # none: nothing was added
    except DataError:
        return False


def response_count(run_dir: Path) -> Callable[[Any], int]:
    """The check's count for any model of the run in ``run_dir`` (a member, a mean of members):
    its k = :data:`CHECK_K` residual correlations with the excitation outside the band on the
    run's validation split, the records read once (an estimate, as every count here)."""
    from canonid.residual_check import CheckedRecords, residual_horizons
    from canonid.runfolder import RunRecipe, run_data

    recipe = RunRecipe.read(run_dir)
    dataset, _ = run_data(recipe)
    checked = CheckedRecords.of(dataset, "val", where=recipe.data)

    def outside(model: Any) -> int:
        _, tests = checked.tests(model, residual_horizons(CHECK_K))
        return int(tests[CHECK_K].outside.sum())

    return outside


def _checked(run_dir: Path, folder: str) -> HorizonCandidate:
    """The check of the run in ``run_dir`` (its data, validation split)."""
    from canonid.learning.model import CONFIG_FILE
    from canonid.residual_check import ResidualRequest, check_residuals
    from canonid.runfolder import RunRecipe

    check = check_residuals(ResidualRequest(run=run_dir, residuals=CHECK_K))
    test = check.tests[CHECK_K]
    recipe = RunRecipe.read(run_dir)
    # the record only: the model's config says it (the check loaded the weights already)
    info = read_json(run_dir / CONFIG_FILE, what="model configuration").get("info", {})
    best = info.get("training", {}).get("best_val_loss")
    return HorizonCandidate(
        horizon=recipe.options().horizon,
        folder=folder,
        window=recipe.window,
        outside=int(test.outside.sum()),
        tests=int(test.outside.size),
        largest=float(test.worst[0]),
        best_val_loss=None if best is None else float(best),
    )


def _runs_entries(folder: Path) -> list[Path]:
    """What a run folder holds of its run: not the check's file and folders, nor hidden entries
    (the lock, files being written, a staged copy)."""
    return [
        p
        for p in sorted(folder.iterdir())
        if p.name != HORIZON_CHECK_FILE and not p.name.startswith(("horizon-", "."))
    ]


def _copy_entry(source: Path, target: Path) -> None:
    """``source`` (a file or a folder) to ``target``, replacing it atomically."""
    if source.is_dir():
        atomic_copy_tree(source, target)
    else:
        atomic_copy(source, target)


def _adopt(run_dir: Path, choice: HorizonChoice) -> None:
    """Make the kept alternative the run folder's run: the run's own entries first copied whole to
    ``RUN/horizon-H`` (staged, then renamed: complete before anything is replaced), then the
    alternative's entries copied in and the run's others removed. Repeating it after an
    interruption finishes it."""
    own = horizon_dir(run_dir, choice.own.horizon)
    alternative = run_path(run_dir, choice.kept.folder, where=f"{run_dir / HORIZON_CHECK_FILE}")
    if not guarded(own).is_dir():
        staged = run_dir / f".{own.name}.staged"
        shutil.rmtree(guarded(staged), ignore_errors=True)
        make_folder(staged)
        for entry in _runs_entries(run_dir):
            _copy_entry(entry, staged / entry.name)
        staged.rename(own)
    theirs = {p.name for p in _runs_entries(alternative)}
    for entry in _runs_entries(alternative):
        _copy_entry(entry, run_dir / entry.name)
    for entry in _runs_entries(run_dir):
        if entry.name not in theirs:
            if guarded(entry).is_dir():
                shutil.rmtree(entry)
            else:
                entry.unlink()


def finish_adoption(run_dir: Path) -> HorizonChoice | None:
    """The choice recorded in ``run_dir`` (``None``: none), its adoption finished first when an
    interruption left it half done (before ``--resume`` reads the run folder's files)."""
    if not (run_dir / HORIZON_CHECK_FILE).is_file():
        return None
    choice = HorizonChoice.read(run_dir)
    if choice.state == "adopting":
        _adopt(run_dir, choice)
        choice = dataclasses.replace(choice, state="decided")
        choice.write(run_dir)
    return choice


def choose_horizon(
    run_dir: Path,
    train_alternative: Callable[[Path, bool, int], None],
    *,
    say: Callable[[str], None] = lambda line: None,
) -> HorizonChoice | None:
    """Check the run in ``run_dir`` and, while every model so far has more residual correlations
    with the excitation than chance allows, train the next alternative of :data:`ALTERNATIVES`
    (``train_alternative(folder, resume, horizon)``: the same request with rollouts of
    ``horizon`` samples into ``folder``, continued when ``resume``); keep the model with the
    fewest correlations outside the band (module docstring). A recorded choice is finished (an
    interrupted adoption) and returned, not made again; ``None`` (and a line said) when the
    validation records are too short for the check."""
    from canonid.learning.training import CHECKPOINT_FILE
    from canonid.residual_check import CONFIDENCE

    if (run_dir / HORIZON_CHECK_FILE).is_file():
        return finish_adoption(run_dir)
    try:
        own = _checked(run_dir, ".")
    except DataError as exc:  # validation records too short for the check at k
        say(f"input response not checked: {exc}")
        return None
    limit = chance_limit(own.tests, CONFIDENCE)
    candidates = [own]
    for horizon in (h for h in ALTERNATIVES if h < own.horizon):
        if min(c.outside for c in candidates) <= limit:
            break
        folder = horizon_dir(run_dir, horizon)
        say(
            f"input response: {candidates[-1].outside} of {candidates[-1].tests} residual "
            f"correlations with the excitation outside the band with H = "
            f"{candidates[-1].horizon} (chance allows {limit}); training with rollouts of "
            f"H = {horizon} too, in {folder}"
        )
        train_alternative(folder, (folder / CHECKPOINT_FILE).is_file(), horizon)
        try:
            candidates.append(_checked(folder, folder.name))
        except DataError as exc:  # its window leaves the records too short for the check
            say(f"input response of the H = {horizon} run not checked ({exc}): not kept")
    # the fewest outside; on a tie the earlier, longer rollouts (the run's own first)
    kept = min(candidates, key=lambda c: c.outside)
    choice = HorizonChoice(tuple(candidates), limit, kept.horizon, confidence=CONFIDENCE)
    if choice.adopted:
        pending = dataclasses.replace(choice, state="adopting")
        pending.write(run_dir)
        _adopt(run_dir, choice)
    choice.write(run_dir)
    return choice
