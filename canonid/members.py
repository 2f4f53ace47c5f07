"""``canonid train --members K``: the run's recipe trained from K seeds, and the model chosen on
validation among the members and the averages of the best of them.

After the run's own training (its search, where one ran), K − 1 more
trainings of the same recipe start from the seeds that follow the run's (``--seed S``: S + 1, …,
S + K − 1), each in ``RUN/members/sS``, a run folder of its own (resumed from its checkpoint when
it was interrupted); ``canonid train`` trains them side by side, one thread each, when the run
may use several cores. They train the network the run's own training settled on (the window and
cubic branch the search kept, what the feedthrough test decided), so every member has the same
architecture. The candidates are each member alone and, for j = 2 … K, the mean of the j
members of lowest validation loss (their regressors averaged at every step:
:func:`canonid.learning.members.average_members`); one routine scores all of them on the run's
validation windows (:func:`canonid.learning.members.validation_losses`), and the lowest becomes
the run folder's model, scored on the test split as the run was. ``members.json`` records the
candidates, their losses and the choice; every member's own model stays in its folder (the run's
first member's too, under ``members/sS``, once another candidate replaced it). The run folder's
``history.csv`` and checkpoint stay the first member's: ``--resume`` continues it, then the
members, then chooses again.

Where the run's input response was checked (:mod:`canonid.horizon_check`: closed-loop data with an
excitation), every candidate is checked the same way, and one whose residuals correlate with the
excitation more often than the run's own model's is not kept: validation loss rewards a model
that reads the state from the feedback, the check does not (``response`` of
:func:`choose_members`; the counts in ``members.json``).
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from canonid.kernel.errors import CheckpointError, OptionError
from canonid.kernel.io import atomic_write_json, guarded, read_json

if TYPE_CHECKING:
    from canonid.learning import Model
    from canonid.runfolder import RunRecipe, RunResult

__all__ = [
    "MEMBERS_DIR",
    "MEMBERS_FILE",
    "MemberChoice",
    "MemberJob",
    "check_members",
    "choose_members",
    "kept_candidate",
    "planned_members",
]

#: the folder of a run folder that holds its members' runs, one ``sS`` folder per seed
MEMBERS_DIR = "members"
#: the members' candidates and the choice among them, in a run folder
MEMBERS_FILE = "members.json"
MEMBERS_FORMAT = "canonid-members"


@dataclass(frozen=True)
class MemberChoice:
    """The candidates of ``--members K`` and the one kept (validation losses normalised, as
    ``fit`` scores an epoch; all computed on the same windows).

    Attributes:
        seeds: the members' seeds, the run's own first.
        losses: each member's validation loss, in the order of ``seeds``.
        means: ``(j, loss)`` of the mean of the j members of lowest loss, j = 2 … K.
        kept: ``"seed S"`` (a member alone) or ``"mean of j"``.
        outside, mean_outside: where the input response was checked, each member's and each
            mean's residual correlations with the excitation outside the band (estimates; a
            candidate with more than the run's own member was not kept), else ``None``.
    """

    seeds: tuple[int, ...]
    losses: tuple[float, ...]
    means: tuple[tuple[int, float], ...]
    kept: str
    outside: tuple[int, ...] | None = None
    mean_outside: tuple[int, ...] | None = None

    @property
    def kept_loss(self) -> float:
        """The kept candidate's validation loss."""
        named = {f"seed {s}": loss for s, loss in zip(self.seeds, self.losses, strict=True)}
        named.update({f"mean of {j}": loss for j, loss in self.means})
        return named[self.kept]

    def summary(self) -> str:
        """The choice in one line (what ``canonid train`` prints)."""
        if self.outside is None or self.mean_outside is None:
            members = ", ".join(f"seed {s} {loss:.4g}" for s, loss in zip(self.seeds, self.losses))
            means = ", ".join(f"mean of {j} {loss:.4g}" for j, loss in self.means)
            return (
                f"members (validation loss): {members}; {means}; kept: {self.kept} "
                f"({self.kept_loss:.4g})"
            )
        members = ", ".join(
            f"seed {s} {loss:.4g} ({n})"
            for s, loss, n in zip(self.seeds, self.losses, self.outside, strict=True)
        )
        means = ", ".join(
            f"mean of {j} {loss:.4g} ({n})"
            for (j, loss), n in zip(self.means, self.mean_outside, strict=True)
        )
        return (
            f"members (validation loss; correlations with the excitation outside the band): "
            f"{members}; {means}; kept: {self.kept} ({self.kept_loss:.4g}), the lowest loss of "
            f"those with at most the run's own {self.outside[0]}"
        )

    def folder(self, seed: int) -> str:
        """Where the member of ``seed`` is, relative to the run folder: the run's own seed is
        the run folder itself while it is kept, else under ``members/``."""
        return "." if seed == self.seeds[0] and self.kept == f"seed {seed}" else member_folder(seed)

    def to_json(self) -> dict[str, Any]:
        members: list[dict[str, Any]] = [
            {"seed": s, "folder": self.folder(s), "val_loss": loss}
            for s, loss in zip(self.seeds, self.losses)
        ]
        means: list[dict[str, Any]] = [{"members": j, "val_loss": loss} for j, loss in self.means]
        body: dict[str, Any] = {"format": MEMBERS_FORMAT, "count": len(self.seeds)}
        if self.outside is not None and self.mean_outside is not None:
            for entry, n in zip([*members, *means], [*self.outside, *self.mean_outside]):
                entry["outside"] = n
            body["criterion"] = (
                "the lowest validation loss among the candidates with at most as many residual "
                "correlations with the excitation outside the band as the run's own member "
                "(estimates, validation split)"
            )
        return {**body, "members": members, "means": means, "kept": self.kept}

    @classmethod
    def read(cls, run_dir: Path) -> MemberChoice:
        """The choice recorded in ``run_dir`` (a :class:`CheckpointError` while its members are
        still training)."""
        path = run_dir / MEMBERS_FILE
        body = read_json(path, what="members")
        if isinstance(body, dict) and body.get("format") == MEMBERS_FORMAT and not body.get("kept"):
            raise CheckpointError(f"{path}: the members have not all trained yet")
        try:
            if body["format"] != MEMBERS_FORMAT:
                raise ValueError
            checked = "criterion" in body
            return cls(
                seeds=tuple(int(m["seed"]) for m in body["members"]),
                losses=tuple(float(m["val_loss"]) for m in body["members"]),
                means=tuple((int(m["members"]), float(m["val_loss"])) for m in body["means"]),
                kept=str(body["kept"]),
                outside=tuple(int(m["outside"]) for m in body["members"]) if checked else None,
                mean_outside=tuple(int(m["outside"]) for m in body["means"]) if checked else None,
            )
        except (KeyError, TypeError, ValueError):
            raise CheckpointError(f"{path} is not a canonid members file") from None


def planned_members(run_dir: Path) -> int | None:
    """The number of members the run in ``run_dir`` was asked for (``members.json``, written
    before the first member trains), or ``None`` where it has no members file."""
    path = run_dir / MEMBERS_FILE
    if not path.is_file():
        return None
    body = read_json(path, what="members")
    count = body.get("count") if isinstance(body, dict) else None
    if not isinstance(body, dict) or body.get("format") != MEMBERS_FORMAT:
        raise CheckpointError(f"{path} is not a canonid members file")
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise CheckpointError(f"{path}: field 'count' must be an integer >= 1, got {count!r}")
    return count


def member_folder(seed: int) -> str:
    """The member of seed ``seed``'s folder, relative to the run folder."""
    return f"{MEMBERS_DIR}/s{seed}"


def check_members(members: int, model: str, *, mode: str) -> None:
    """Refuse ``--members`` where it does not apply: below 1, for a model other than Ours
    (MLP), or with a list of windows or ``--hidden auto`` (whose candidates are chosen
    already)."""
    if isinstance(members, bool) or not isinstance(members, int) or members < 1:
        raise OptionError(f"--members must be an integer >= 1, got {members!r}")
    if members == 1:
        return
    if model != "mlp":
        raise OptionError(f"--members averages Ours (MLP) networks (mlp), not {model}")
    if mode == "select":
        raise OptionError(
            "--members does not combine with a list of windows or --hidden auto: give one "
            "window, or none for the search"
        )


def _finite(loss: float) -> float:
    return loss if math.isfinite(loss) else math.inf


def kept_candidate(
    seeds: Sequence[int],
    losses: Sequence[float],
    means: Sequence[tuple[int, float]],
    outside: Sequence[int] | None = None,
) -> str:
    """The candidate of lowest validation loss, ``"seed S"`` or ``"mean of j"``: the members in
    seed order, then the means by size, the first on a tie; a loss that is not finite never
    wins (the run's own member where none is finite). ``outside``: every candidate's count of
    residual correlations with the excitation outside the band, in the same order (members,
    then means); a candidate with more than the run's own member (the first) is not kept."""
    named = [(loss, f"seed {s}") for s, loss in zip(seeds, losses, strict=True)]
    named += [(loss, f"mean of {j}") for j, loss in means]
    if outside is not None:
        named = [c for c, n in zip(named, outside, strict=True) if n <= outside[0]]
    finite = [c for c in named if math.isfinite(c[0])]
    return min(finite, key=lambda c: c[0])[1] if finite else f"seed {seeds[0]}"


@dataclass(frozen=True)
class MemberJob:
    """One member to train: its recipe, its run folder, and whether to resume it there (its
    checkpoint exists)."""

    recipe: RunRecipe
    folder: Path
    resume: bool


def member_recipe(recipe: RunRecipe, model: Model, seed: int) -> RunRecipe:
    """``recipe`` from ``seed``, training the network ``model`` (the run's first member) has:
    the search's and the feedthrough test's decisions taken over, not made again."""
    config = model.net.config()
    net_options = dict(recipe.net_options)
    net_options["feedthrough"] = bool(config["feedthrough"])
    net_options["cubic"] = int(config.get("cubic", 0))
    return dataclasses.replace(
        recipe,
        net_options=net_options,
        train_options={**recipe.train_options, "seed": seed},
        members=None,  # a member is one training: it trains no members of its own
    )


def choose_members(
    first: RunResult,
    run_dir: Path,
    members: int,
    *,
    train: Callable[[Sequence[MemberJob]], list[Model]],
    eval_horizon: int | None = None,
    figure_format: str = "png",
    response: Callable[[Model], int] | None = None,
) -> MemberChoice:
    """Train the members of the run ``first`` (its own training, in ``run_dir``) that follow
    it, choose among them and their means on validation, and make the choice the run folder's
    model (see the module docstring). ``train(jobs)`` trains (or resumes) every member's
    :class:`MemberJob` and returns their models in the same order; they are independent, so
    it may train them side by side. ``response(model)``: a candidate's count of residual
    correlations with the excitation outside the band (:func:`canonid.horizon_check.
    response_count`); given, no candidate with more than the run's own member is kept."""
    from canonid.learning.members import average_members, validation_losses
    from canonid.learning.training import CHECKPOINT_FILE
    from canonid.runfolder import load_splits, rescore_run

    recipe = first.recipe
    seed = int(recipe.options().seed)
    seeds = tuple(seed + i for i in range(members))
    # the plan first, so that --resume continues the members after an interruption
    atomic_write_json(
        run_dir / MEMBERS_FILE,
        {"format": MEMBERS_FORMAT, "count": members, "members": [], "means": [], "kept": None},
    )
    folders = {s: run_dir / member_folder(s) for s in seeds[1:]}
    jobs = [
        MemberJob(member_recipe(recipe, first.fit.model, s), f, (f / CHECKPOINT_FILE).is_file())
        for s, f in folders.items()
    ]
    models: list[Model] = [first.fit.model, *(train(jobs) if jobs else [])]
    _, _, val, _, _ = load_splits(recipe)
    options = recipe.options()
    losses = validation_losses(models, val, options)
    order = sorted(range(members), key=lambda i: (_finite(losses[i]), i))
    sizes = range(2, members + 1)
    means = [average_members([models[i] for i in order[:j]]) for j in sizes]
    mean_losses = tuple(zip(sizes, validation_losses(means, val, options) if means else []))
    outside = None if response is None else tuple(response(m) for m in models)
    mean_outside = None if response is None else tuple(response(m) for m in means)
    counts = None if outside is None or mean_outside is None else (*outside, *mean_outside)
    kept = kept_candidate(seeds, losses, mean_losses, counts)
    model = {
        **{f"seed {s}": m for s, m in zip(seeds, models, strict=True)},
        **{f"mean of {j}": m for j, m in zip(sizes, means, strict=True)},
    }[kept]
    choice = MemberChoice(
        seeds=seeds,
        losses=tuple(losses),
        means=mean_losses,
        kept=kept,
        outside=outside,
        mean_outside=mean_outside,
    )
    own = run_dir / member_folder(seed)  # where the run's own model waits while another is kept
    if kept != f"seed {seed}":
        first.fit.model.save(own)
        # the recipe's training record, and where the choice is written down
        members_info = {"kept": kept, "seeds": list(seeds), "file": MEMBERS_FILE}
        model.info = {**first.fit.model.info, "members": members_info}
    if kept != f"seed {seed}" or own.is_dir():  # a resumed choice may keep the run's own again
        model.save(run_dir)
        rescore_run(run_dir, recipe, model, eval_horizon=eval_horizon, figure_format=figure_format)
    if kept == f"seed {seed}" and own.is_dir():
        shutil.rmtree(guarded(own))
    atomic_write_json(run_dir / MEMBERS_FILE, choice.to_json())
    return choice
