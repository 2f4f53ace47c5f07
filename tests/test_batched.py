"""Candidates trained as stacked weights: each equals the same candidate trained alone by ``fit``,
selection reads validation only, same seed gives the same bytes, bad candidates are named."""

from __future__ import annotations

import importlib
import inspect
import math
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from learning_helpers import damped_split

from canonid.kernel.errors import CheckpointError, OptionError
from canonid.learning import TrainOptions, fit
from canonid.learning.batched import (
    Candidate,
    Ensemble,
    _StackedMLP,
    candidate_grid,
    fit_batched,
)

# the network options spelt out in full, so that the tests do not follow the defaults; the
# skip path and the residual output are on so that every branch of the stacked rollout runs;
# stacked candidates are plain networks (no cubic branch)
TINY = {
    "hidden": [16, 16],
    "cubic": 0,
    "feedthrough": True,
    "residual": True,
    "activation": "silu",
    "linear": "skip",
}


@pytest.fixture(scope="module")
def data():
    return damped_split(4, 2, 60)


def options(**kw) -> TrainOptions:
    base = {
        "epochs": 5,
        "batch_size": 8,
        "lr": 3e-3,
        "horizon": 8,
        "curriculum_epochs": 3,
        "windows_per_epoch": 24,
        "grad_clip": 1.0,
        "seed": 7,
        "device": "cpu",
    }
    return TrainOptions(**{**base, **kw})


def alone(train, val, candidate: Candidate, opts: TrainOptions, window: int = 3):
    """The candidate trained by ``fit``, on its own."""
    net = dict(TINY)
    if candidate.get("hidden", None) is not None:
        net["hidden"] = list(candidate.get("hidden", ()))
    return fit(
        train,
        val,
        model="mlp",
        window=candidate.get("window", window),
        options=candidate.train_options(opts),
        net_options=net,
    )


def assert_same_run(batched, single) -> None:
    """Weights, validation and training losses equal to float32 tolerance; same epochs."""
    assert (batched.best_epoch, batched.epochs_run, batched.stopped) == (
        single.best_epoch,
        single.epochs_run,
        single.stopped,
    )
    mine, theirs = batched.model.net.state_dict(), single.model.net.state_dict()
    assert mine.keys() == theirs.keys()
    for key in mine:
        torch.testing.assert_close(mine[key], theirs[key], rtol=1e-5, atol=1e-6, msg=key)
    assert len(batched.history) == len(single.history)
    for a, b in zip(batched.history, single.history, strict=True):
        assert (a["epoch"], a["horizon"]) == (b["epoch"], b["horizon"])
        assert a["lr"] == pytest.approx(b["lr"], rel=1e-12)
        for key in ("train_loss", "val_loss"):
            if b[key] is None:
                assert a[key] is None
            else:
                assert a[key] == pytest.approx(b[key], rel=1e-5, nan_ok=True)
    assert batched.best_val_loss == pytest.approx(single.best_val_loss, rel=1e-5)


# every candidate keeps options.seed, so fit draws the same sub-windows as the stack
VARIANTS = [
    Candidate.of(),
    Candidate.of(lr=1e-3, lr_final=1e-4),
    Candidate.of(weight_decay=1e-2, grad_clip=0.05),
    Candidate.of(grad_clip=None),
    Candidate.of(hidden=(8, 8)),  # a second stack
    Candidate.of(hidden=(8, 8), lr=1e-2),
    Candidate.of(window=2),  # a third stack, on sub-windows of its own span
]


@pytest.mark.parametrize(
    "opts",
    [options(), options(ema_decay=0.9), options(epochs=15, patience=2, lr=1e-2)],
    ids=["plain", "weight-average", "early-stopping"],
)
def test_each_batched_candidate_equals_the_same_candidate_trained_alone(data, opts):
    train, val = data
    other_seed = Candidate.of(seed=99)  # stacked with the others; must not change them
    result = fit_batched(
        train, val, [*VARIANTS, other_seed], window=3, options=opts, net_options=TINY
    )
    for candidate, run in zip(VARIANTS, result.runs, strict=False):
        assert_same_run(run, alone(train, val, candidate, opts))
    if opts.patience is not None:  # the early stops differ, so the stack shrank mid-run
        assert len({run.epochs_run for run in result.runs}) > 1


@pytest.mark.parametrize("poison", ["once", "always"])
def test_a_non_finite_loss_stops_or_recovers_its_candidate_alone(data, monkeypatch, poison):
    """Candidate 1's 3rd batch (or every batch from the 5th) is not finite, as the same
    poisoning of fit: it recovers (or diverges) as fit does; candidate 0 is untouched."""
    from canonid.learning.nets import OursMLP

    train, val = data
    opts = options(epochs=6)
    hit = (lambda n: n == 3) if poison == "once" else (lambda n: n > 4)

    original_stacked, calls = _StackedMLP.rollout, {"n": 0}

    def stacked(self, params, scale, u, y, horizon):
        pred = original_stacked(self, params, scale, u, y, horizon)
        if not torch.is_grad_enabled():  # validation
            return pred
        calls["n"] += 1
        if hit(calls["n"]) and pred.shape[0] == 2:  # while candidate 1 is in the stack
            # a factor, not torch.where: where's gradient would put 0 · NaN on every row
            factor = torch.ones(pred.shape[0], 1, 1, 1)
            factor[1] = math.nan
            pred = pred * factor
        return pred

    monkeypatch.setattr(_StackedMLP, "rollout", stacked)
    result = fit_batched(
        train,
        val,
        [Candidate.of(), Candidate.of(lr=2e-3)],
        window=3,
        options=opts,
        net_options=TINY,
    )
    assert result.runs[1].stopped == ("completed" if poison == "once" else "diverged")
    assert_same_run(result.runs[0], alone(train, val, Candidate.of(), opts))

    original_loss, single = OursMLP.training_loss, {"n": 0}

    def poisoned(self, u, y, *, alpha_first):
        single["n"] += 1
        loss, parts = original_loss(self, u, y, alpha_first=alpha_first)
        return (loss * math.nan if hit(single["n"]) else loss), parts

    monkeypatch.setattr(OursMLP, "training_loss", poisoned)
    assert_same_run(result.runs[1], alone(train, val, Candidate.of(lr=2e-3), opts))


def test_selection_reads_validation_only(data, monkeypatch):
    """No test split is an argument, nothing is scored on data other than validation: the
    chosen candidate has the lowest best validation loss, and the ensemble is kept only when
    its validation loss is lower."""
    from canonid.learning.model import Model

    evaluation = importlib.import_module("canonid.learning.evaluate")

    assert not any("test" in name for name in inspect.signature(fit_batched).parameters)

    def forbidden(*args, **kwargs):
        raise AssertionError("selection must not score data other than validation")

    for owner, name in ((evaluation, "evaluate"), (Model, "simulate"), (Model, "predict")):
        monkeypatch.setattr(owner, name, forbidden)
    train, val = data
    result = fit_batched(
        train,
        val,
        candidate_grid(seed=[0, 1, 2], lr=[1e-3, 3e-3]),
        window=3,
        options=options(),
        net_options=TINY,
        ensemble=3,
    )
    losses = [run.best_val_loss for run in result.runs]
    assert result.chosen == int(np.argmin(losses))
    assert result.ensemble_val_loss is not None
    top = tuple(sorted(range(len(losses)), key=lambda i: (losses[i], i))[:3])
    if result.ensemble is not None:
        assert result.ensemble == top and result.val_loss == result.ensemble_val_loss
        assert result.ensemble_val_loss < losses[result.chosen] * (1 + 1e-5)
    else:
        assert result.val_loss == losses[result.chosen]
        assert result.ensemble_val_loss > losses[result.chosen] * (1 - 1e-5)
    table = result.table()
    assert [row["chosen"] for row in table].count(True) == 1
    assert table[result.chosen]["best_val_loss"] == losses[result.chosen]


def test_ties_choose_the_first_candidate_and_an_ensemble_averages_its_members(data):
    train, val = data
    twins = [Candidate.of(seed=3), Candidate.of(seed=3)]  # the same run twice: equal losses
    result = fit_batched(train, val, twins, window=3, options=options(), net_options=TINY)
    assert result.runs[0].best_val_loss == result.runs[1].best_val_loss
    assert result.chosen == 0
    # an ensemble of twins scores what each scores, so it is not kept
    assert result.ensemble is None and result.model is result.runs[0].model
    members = [result.runs[0].model, result.runs[1].model]
    u, y = val[0].u[None], val[0].y[None, :3]
    np.testing.assert_allclose(
        Ensemble(members).simulate(u, y),
        (members[0].simulate(u, y) + members[1].simulate(u, y)) / 2,
    )


def test_the_same_seed_gives_the_same_bytes(data, tmp_path):
    train, val = data
    grid = candidate_grid(seed=[0, 1], weight_decay=[0.0, 1e-3])
    runs = [
        fit_batched(train, val, grid, window=3, options=options(), net_options=TINY)
        for _ in range(2)
    ]
    for i in range(len(grid)):
        folders = [r.runs[i].model.save(tmp_path / f"{k}-{i}") for k, r in enumerate(runs)]
        for name in ("weights.pt", "config.json", "normalisation.json"):
            assert (folders[0] / name).read_bytes() == (folders[1] / name).read_bytes()
        strip = [
            [{k: v for k, v in row.items() if k != "seconds"} for row in r.runs[i].history]
            for r in runs
        ]
        assert strip[0] == strip[1]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Candidate.of(activation="tanh"), "cannot vary between stacked candidates"),
        (lambda: Candidate.of(lr=-1.0).train_options(options()), "lr must be a positive"),
    ],
)
def test_bad_candidates_are_named(make, message):
    with pytest.raises(OptionError, match=message):
        make()


def test_no_candidate_is_refused(data):
    train, val = data
    with pytest.raises(OptionError, match="at least one candidate"):
        fit_batched(train, val, [], window=3, options=options())


class _Interrupt(Exception):
    """Stands for a process that stops between two epochs (a checkpoint was written)."""


def _stop_after(epoch: int):
    def callback(done: int) -> None:
        if done == epoch:
            raise _Interrupt

    return callback


def _same_result(a, b, tmp_path) -> None:
    assert (a.chosen, a.ensemble, a.ensemble_val_loss) == (
        b.chosen,
        b.ensemble,
        b.ensemble_val_loss,
    )
    for i, (ra, rb) in enumerate(zip(a.runs, b.runs, strict=True)):
        fa, fb = ra.model.save(tmp_path / f"a-{i}"), rb.model.save(tmp_path / f"b-{i}")
        for name in ("weights.pt", "config.json", "normalisation.json"):
            assert (fa / name).read_bytes() == (fb / name).read_bytes(), (i, name)
        strip = [
            [{k: v for k, v in row.items() if k != "seconds"} for row in r.history]
            for r in (ra, rb)
        ]
        assert strip[0] == strip[1]
        assert (ra.best_epoch, ra.stopped, ra.epochs_run) == (
            rb.best_epoch,
            rb.stopped,
            rb.epochs_run,
        )


def test_an_interrupted_run_resumed_gives_the_bytes_of_an_uninterrupted_one(data, tmp_path):
    train, val = data
    # two windows (two stacks); two candidates stop early at epoch 6, after the interruption
    grid = [*candidate_grid(seed=[0, 1], lr=[3e-3, 1e-2]), Candidate.of(window=4)]
    opts = options(epochs=8, checkpoint_every=2, patience=1, val_every=1, curriculum_epochs=1)
    common = {"window": 3, "options": opts, "net_options": TINY}
    whole = fit_batched(train, val, grid, **common)
    assert sorted(r.stopped for r in whole.runs).count("early_stopping") == 2
    with pytest.raises(_Interrupt):
        fit_batched(train, val, grid, **common, run_dir=tmp_path, callback=_stop_after(5))
    resumed = fit_batched(train, val, grid, **common, run_dir=tmp_path, resume=True)
    _same_result(whole, resumed, tmp_path / "models")


KILLED_BATCHED = """
import os, signal, sys
sys.path.insert(0, sys.argv[1])
from test_batched import TINY, data, options
from canonid.learning.batched import candidate_grid, fit_batched

train, val = data.__wrapped__()
grid = candidate_grid(seed=[0, 1, 2])
kill = int(sys.argv[3])

def callback(epoch):
    if epoch == kill:
        os.kill(os.getpid(), signal.SIGKILL)  # after epoch 5's checkpoint (every 2: epoch 4)

fit_batched(train, val, grid, window=3, options=options(epochs=7, checkpoint_every=2),
            net_options=TINY, run_dir=sys.argv[2], callback=callback)
"""


def test_kill_9_then_resume_gives_the_same_bytes(data, tmp_path):
    train, val = data
    grid = candidate_grid(seed=[0, 1, 2])
    opts = options(epochs=7, checkpoint_every=2)
    tests = str(Path(__file__).resolve().parent)
    proc = subprocess.run(
        [sys.executable, "-c", KILLED_BATCHED, tests, str(tmp_path), "5"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    resumed = fit_batched(
        train, val, grid, window=3, options=opts, net_options=TINY, run_dir=tmp_path, resume=True
    )
    whole = fit_batched(train, val, grid, window=3, options=opts, net_options=TINY)
    _same_result(whole, resumed, tmp_path / "models")


def test_a_checkpoint_of_other_candidates_is_refused(data, tmp_path):
    train, val = data
    opts = options(epochs=2)
    fit_batched(
        train,
        val,
        candidate_grid(seed=[0, 1]),
        window=3,
        options=opts,
        net_options=TINY,
        run_dir=tmp_path,
    )
    with pytest.raises(CheckpointError, match="candidates"):
        fit_batched(
            train,
            val,
            candidate_grid(seed=[0, 2]),
            window=3,
            options=opts,
            net_options=TINY,
            run_dir=tmp_path,
            resume=True,
        )
    with pytest.raises(CheckpointError, match="needs the run_dir"):
        fit_batched(train, val, candidate_grid(seed=[0]), window=3, options=opts, resume=True)
