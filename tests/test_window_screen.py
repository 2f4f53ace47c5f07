"""The window chosen on validation: ``canonid train`` without ``--window`` screens the candidate
windows briefly (:mod:`canonid.learning.screen`) and trains the one with the lowest validation
loss as ``--window`` would; ``--window L`` trains exactly L."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from cli_helpers import one_line_error
from hypothesis import given, settings
from hypothesis import strategies as st
from learning_helpers import damped_siso, trajectories

import canonid
from canonid.cli import main
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.kernel.errors import CheckpointError, OptionError
from canonid.learning import TrainOptions
from canonid.learning.screen import (
    SCREEN_FILE,
    SCREEN_TOLERANCE,
    ScreenCandidate,
    WindowScreen,
    choose_window,
    screen_options,
    screen_windows,
)
from canonid.training import parse_window

FAST = ["--profile", "tiny", "--epochs", "3", "--no-progress", "--device", "cpu", "--threads", "1"]


def siso_file(folder, *, T=70, test_scale=1.0):
    """A small canonid dataset of a damped SISO system; ``test_scale`` multiplies the test
    split's outputs (the screen must not notice)."""
    system = damped_siso()

    def make(n, seed, scale=1.0):
        return tuple(
            Trajectory(u=t.u, y=t.y * scale, y_clean=t.y_clean * scale)
            for t in trajectories(system, n, T, noise=0.01, seed=seed)
        )

    ds = Dataset(
        splits={"train": make(3, 1), "val": make(1, 2), "test": make(2, 3, test_scale)},
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
    )
    return ds.save(folder / "dataset.npz")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return siso_file(tmp_path_factory.mktemp("data"))


@pytest.fixture(scope="module")
def screened(data, tmp_path_factory):
    run = tmp_path_factory.mktemp("screen") / "run"
    assert main(["train", str(data), "--out", str(run), *FAST]) == 0
    return run


def weights(run):
    return torch.load(run / "weights.pt", weights_only=True)


# ------------------------------------------------------------------------------ the grammar
@pytest.mark.parametrize(
    ("text", "window"),
    [(None, None), ("auto", "auto"), ("10", 10), ("5,10,20", (5, 10, 20)), ("5,5,10", (5, 10))],
)
def test_window_reads_one_window_a_list_or_auto(text, window):
    assert parse_window(text) == window


@pytest.mark.parametrize("text", ["0", "x", "5,,10", "5,-1", "²", "10.5", ""])
def test_a_bad_window_is_one_line_naming_the_option(text, data, tmp_path, capsys):
    with pytest.raises(OptionError, match="--window: expected an integer >= 1"):
        parse_window(text)
    code = main(["train", str(data), "--window", text, "--out", str(tmp_path / "r"), *FAST])
    one_line_error(capsys, code, "--window: expected an integer >= 1")
    assert not (tmp_path / "r").exists()


def test_combinations_the_screen_does_not_make_are_refused(screened, data, tmp_path, capsys):
    code = main(["train", str(data), "--hidden", "auto", "--out", str(tmp_path / "r"), *FAST])
    one_line_error(capsys, code, "--hidden auto needs the window")
    code = main(["train", str(data), "--workers", "2", "--out", str(tmp_path / "r"), *FAST])
    one_line_error(capsys, code, "--workers applies to a list of windows or --hidden auto only")
    code = main(["train", "--resume", "--out", str(screened), "--window", "auto", *FAST[:-2]])
    one_line_error(capsys, code, "--window auto does not combine with --resume")
    assert not (tmp_path / "r").exists()


# ------------------------------------------------------------------------------ the screen
def test_an_explicit_window_trains_exactly_that_window(data, tmp_path):
    run = tmp_path / "l7"
    assert main(["train", str(data), "--window", "7", "--out", str(run), *FAST]) == 0
    assert json.loads((run / "run.json").read_text())["window"] == 7
    assert json.loads((run / "config.json").read_text())["net"]["window"] == 7
    assert not (run / SCREEN_FILE).exists()


def test_no_window_chooses_the_shortest_candidate_near_the_lowest_validation_loss(screened, capsys):
    screen = WindowScreen.read(screened)
    windows = [c.window for c in screen.candidates]
    # T = 70, the tiny profile's rollouts of 10 to train and 20 to validate (at least half of
    # them left after ℓ): ℓ = 80 does not fit
    assert windows == [10, 20, 40]
    assert screen.options["val_horizon"] == 20  # every candidate on the same rollouts
    lowest = min(c.best_val_loss for c in screen.candidates)
    near = [c.window for c in screen.candidates if c.best_val_loss <= SCREEN_TOLERANCE * lowest]
    assert screen.tolerance == SCREEN_TOLERANCE and screen.chosen == min(near)
    assert json.loads((screened / "run.json").read_text())["window"] == screen.chosen
    assert json.loads((screened / "config.json").read_text())["net"]["window"] == screen.chosen
    assert screen.epochs == 1 and all(c.epochs_run == 1 for c in screen.candidates)  # 10 % of 3


def test_the_screened_run_is_the_run_of_the_chosen_window(screened, data, tmp_path):
    """The full run after the screen is ``--window <chosen>``'s, weight for weight; the same
    seed gives the same choice and the same weights again."""
    chosen = WindowScreen.read(screened).chosen
    run = tmp_path / "explicit"
    assert main(["train", str(data), "--window", str(chosen), "--out", str(run), *FAST]) == 0
    again = tmp_path / "again"
    assert main(["train", str(data), "--out", str(again), *FAST]) == 0
    for other in (run, again):
        mine, theirs = weights(screened), weights(other)
        assert mine.keys() == theirs.keys()
        assert all(torch.equal(mine[k], theirs[k]) for k in mine)
    first, second = WindowScreen.read(screened), WindowScreen.read(again)
    assert [c.best_val_loss for c in first.candidates] == [
        c.best_val_loss for c in second.candidates
    ]
    assert (screened / "weights.pt").read_bytes() == (again / "weights.pt").read_bytes()


def test_canonid_fit_without_a_window_screens_as_the_command_line_does(screened, data, tmp_path):
    """``canonid.fit`` without ``window`` runs the same screen (same table, same choice) and
    returns the chosen window's model with the table; with ``run_dir`` the table is written,
    and ``resume=True`` keeps it instead of screening again."""
    import canonid

    ds = Dataset.load(data)
    options = canonid.train_options("tiny", epochs=3, device="cpu")
    run = tmp_path / "api"
    result = canonid.fit(ds.split("train"), ds.split("val"), options=options, run_dir=run)
    cli = WindowScreen.read(screened)
    assert result.screen is not None and result.model.window == result.screen.chosen
    assert result.screen.chosen == cli.chosen
    assert [c.best_val_loss for c in result.screen.candidates] == [
        c.best_val_loss for c in cli.candidates
    ]
    assert WindowScreen.read(run).to_dict() == result.screen.to_dict()
    explicit = canonid.fit(ds.split("train"), ds.split("val"), window=cli.chosen, options=options)
    assert explicit.screen is None and explicit.best_val_loss == result.best_val_loss
    recorded = (run / SCREEN_FILE).read_bytes()
    longer = canonid.train_options("tiny", epochs=4, device="cpu")
    resumed = canonid.fit(
        ds.split("train"), ds.split("val"), options=longer, run_dir=run, resume=True
    )
    assert (run / SCREEN_FILE).read_bytes() == recorded and resumed.epochs_run == 4
    assert resumed.model.window == cli.chosen


def test_canonid_fit_with_no_window_that_fits_is_one_line(tmp_path):
    import canonid

    short = [Trajectory(u=np.zeros((9, 1)), y=np.zeros((9, 1)))]
    with pytest.raises(canonid.CanonidError, match="window='auto': none of the windows"):
        canonid.fit(short, short, options=canonid.train_options("tiny", epochs=1))


def test_the_screen_never_reads_the_test_split(data, tmp_path):
    poisoned = siso_file(tmp_path / "poisoned-data", test_scale=1e6)
    runs = []
    for name, path in (("clean", data), ("poisoned", poisoned)):
        run = tmp_path / f"run-{name}"
        assert main(["train", str(path), "--out", str(run), *FAST]) == 0
        runs.append(WindowScreen.read(run))
    assert runs[0].to_dict()["chosen"] == runs[1].to_dict()["chosen"]
    assert [c.best_val_loss for c in runs[0].candidates] == [
        c.best_val_loss for c in runs[1].candidates
    ]


def test_resume_keeps_the_recorded_choice(screened, tmp_path, capsys):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(screened, run)
    recorded = (run / SCREEN_FILE).read_bytes()
    capsys.readouterr()
    argv = [
        "train",
        "--resume",
        "--out",
        str(run),
        "--epochs",
        "4",
        "--no-progress",
        "--threads",
        "1",
    ]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert (run / SCREEN_FILE).read_bytes() == recorded  # not screened again
    chosen = WindowScreen.read(run).chosen
    assert f"window ℓ = {chosen} chosen on validation" in out and "after 4 epochs" in out
    assert json.loads((run / "run.json").read_text())["window"] == chosen


def test_the_printed_line_names_the_choice_and_the_candidates(data, tmp_path, capsys):
    run = tmp_path / "run"
    capsys.readouterr()
    assert main(["train", str(data), "--out", str(run), *FAST]) == 0
    screen = WindowScreen.read(run)
    out = capsys.readouterr().out
    assert (
        f"window ℓ = {screen.chosen} chosen on validation from 10, 20, 40 "
        f"(screen of 1 epoch each, the shortest within {SCREEN_TOLERANCE:g}× of the lowest loss); "
        "--window L trains L"
    ) in out


# ------------------------------------------------------------------------------ the caps
def test_candidates_longer_than_the_records_allow_are_not_tried(tmp_path):
    """T = 35: ℓ ≤ 25 leaves half the validation rollout of 20; all candidates are validated
    on the 15 steps that ℓ = 20 leaves."""
    data = siso_file(tmp_path / "d", T=35)
    run = tmp_path / "run"
    assert main(["train", str(data), "--out", str(run), *FAST]) == 0
    screen = WindowScreen.read(run)
    assert [c.window for c in screen.candidates] == [10, 20]
    assert screen.options["val_horizon"] == 15


def test_max_window_caps_the_screen_as_a_scoring_rule_would(data, tmp_path, capsys):
    """``--max-window 20`` (a rule with n_init = 20) screens ℓ = 10 and 20 only; canonid.fit's
    ``max_window`` the same; the cap outside a screen, or below every window, is one line."""
    run = tmp_path / "run"
    assert main(["train", str(data), "--max-window", "20", "--out", str(run), *FAST]) == 0
    assert [c.window for c in WindowScreen.read(run).candidates] == [10, 20]
    ds = Dataset.load(data)
    options = canonid.train_options("tiny", epochs=3, device="cpu")
    found = canonid.fit(ds.split("train"), ds.split("val"), max_window=20, options=options)
    assert [c.window for c in found.screen.candidates] == [10, 20]
    with pytest.raises(OptionError, match="max_window caps the screen"):
        canonid.fit(ds.split("train"), ds.split("val"), window=10, max_window=20)
    for extra, message in (
        (["--max-window", "5"], "--max-window 5 is below every window the screen tries"),
        (["--max-window", "20", "--window", "10"], "--max-window caps the screen's windows"),
    ):
        code = main(["train", str(data), *extra, "--out", str(tmp_path / "r"), *FAST])
        one_line_error(capsys, code, message)
    code = main(["train", "--resume", "--out", str(run), "--max-window", "20", *FAST[:-2]])
    one_line_error(capsys, code, "--max-window caps the screen's windows")
    assert not (tmp_path / "r").exists()


def test_no_window_that_fits_is_one_line_naming_the_data(tmp_path, capsys):
    data = siso_file(tmp_path / "d", T=14)  # ℓ = 10 needs 10 + 10 samples to train
    run = tmp_path / "run"
    code = main(["train", str(data), "--out", str(run), *FAST])
    one_line_error(capsys, code, str(data), "no candidate window of [10, 20, 40, 80] fits")
    assert not run.exists()


# ------------------------------------------------------------------------------ closed forms
def delayed(d: int, n: int, T: int, seed: int) -> list[Trajectory]:
    """``y_t = u_{t−d}`` with white-noise inputs: a window shorter than ``d`` cannot predict."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        u = rng.standard_normal((T + d, 1))
        out.append(Trajectory(u=u[d:], y=u[:T]))
    return out


@settings(max_examples=8, deadline=None)
@given(d=st.integers(1, 12))
def test_a_delay_of_d_samples_is_screened_to_a_window_of_at_least_d(d):
    """ARX (least squares) sees u_{t−d} only when ℓ ≥ d: the shorter windows keep an error of
    about the input's variance, the others none, so the screen picks a window ≥ d."""
    opts = TrainOptions(epochs=1, horizon=5, val_horizon=10, val_stride=3, device="cpu")
    windows = (2, 4, 8, 16)
    screen = screen_windows(
        delayed(d, 3, 200, 0), delayed(d, 1, 200, 1), windows=windows, model="arx", options=opts
    )
    assert screen.chosen >= d
    for c in screen.candidates:
        assert c.best_val_loss is not None
        assert (c.best_val_loss > 0.3) if c.window < d else (c.best_val_loss < 1e-6)


def test_a_failing_candidate_is_recorded_and_left_out(monkeypatch):
    import canonid.learning.training as training

    real = training.fit

    def fit(*args, window, **kwargs):
        if window == 4:
            raise RuntimeError("the rollout blew up\nsecond line")
        return real(*args, window=window, **kwargs)

    monkeypatch.setattr(training, "fit", fit)
    opts = TrainOptions(epochs=1, horizon=5, val_horizon=10, device="cpu")
    train, val = delayed(3, 2, 100, 0), delayed(3, 1, 100, 1)
    screen = screen_windows(train, val, windows=(2, 4, 8), model="arx", options=opts)
    failed = next(c for c in screen.candidates if c.window == 4)
    assert failed.stopped == "failed" and failed.error == "the rollout blew up"
    assert failed.best_val_loss is None and screen.chosen == 8
    monkeypatch.setattr(training, "fit", lambda *a, **k: fit(*a, **{**k, "window": 4}))
    with pytest.raises(OptionError, match="no candidate window reached a finite validation"):
        screen_windows(train, val, windows=(2, 8), model="arx", options=opts)


# ------------------------------------------------------------------------------ the record
@given(
    fraction=st.floats(0.01, 1.0),
    epochs=st.integers(1, 2000),
    curriculum=st.integers(0, 500),
    patience=st.one_of(st.none(), st.integers(1, 500)),
)
def test_the_screens_options_are_the_profiles_scaled(fraction, epochs, curriculum, patience):
    full = TrainOptions(epochs=epochs, curriculum_epochs=curriculum, patience=patience)
    short = screen_options(full, fraction)
    assert short.epochs == max(1, round(epochs * fraction)) <= epochs
    assert short.curriculum_epochs == round(curriculum * fraction)
    assert short.patience == (None if patience is None else max(1, round(patience * fraction)))
    assert (short.lr, short.horizon, short.seed) == (full.lr, full.horizon, full.seed)


def test_the_record_reads_back_and_a_malformed_one_is_refused(tmp_path):
    rows = (
        ScreenCandidate(5, 0.5, 3, 4, "completed", None, 1.0),
        ScreenCandidate(10, None, 0, 0, "failed", "boom", 0.0),
    )
    screen = WindowScreen(rows, 5, 0.1, TrainOptions(epochs=4).to_dict())
    screen.write(tmp_path)
    assert WindowScreen.read(tmp_path) == screen
    body = json.loads((tmp_path / SCREEN_FILE).read_text())
    with pytest.raises(CheckpointError, match="chosen window 20 is not a candidate"):
        WindowScreen.from_dict({**body, "chosen": 20}, where="x")
    with pytest.raises(CheckpointError, match="malformed window screen"):
        WindowScreen.from_dict({**body, "candidates": [{"window": 5}]}, where="x")
    with pytest.raises(CheckpointError, match="not a canonid window screen"):
        WindowScreen.from_dict({"format": "other"}, where="x")
    assert math.isclose(screen.cpu_seconds, 1.0)


@given(
    st.dictionaries(
        st.integers(1, 200), st.floats(1e-9, 1e3, allow_nan=False), min_size=1, max_size=6
    ),
    st.floats(1.0, 3.0),
)
def test_the_rule_keeps_the_shortest_window_near_the_lowest_loss(losses, tolerance):
    chosen = choose_window(losses, tolerance)
    lowest = min(losses.values())
    assert losses[chosen] <= tolerance * lowest
    assert all(losses[w] > tolerance * lowest for w in losses if w < chosen)
    # tolerance 1: the lowest loss itself, the shortest window on a tie
    exact = choose_window(losses, 1.0)
    assert losses[exact] == lowest and exact == min(w for w, v in losses.items() if v == lowest)


def test_a_longer_window_must_be_clearly_better():
    # near-ties go to the shorter window; a several-fold gain to the longer one
    assert choose_window({10: 2.05e-4, 20: 1.98e-4}) == 10
    assert choose_window({10: 4.04e-4, 20: 2.61e-4, 40: 2.86e-4}) == 10  # 1.55× is a near-tie
    assert choose_window({10: 1.4e-2, 20: 1.2e-3, 40: 2.4e-4, 80: 3.3e-4}) == 40


def test_one_window_alone_is_chosen_without_training():
    # a screen of one candidate has nothing to rank: no CPU is spent on it
    screen = screen_windows([], [], windows=(10,))
    assert screen.chosen == 10 and screen.cpu_seconds == 0
    assert screen.candidates[0].best_val_loss is None


# ------------------------------------------------------------------------------ full runs after
def _row(window, loss, epochs_run, stopped="early_stopping"):
    return ScreenCandidate(window, loss, max(epochs_run - 5, 0), epochs_run, stopped, None, 1.0)


def _screen_of(losses):
    rows = tuple(_row(w, loss, 6) for w, loss in losses.items())
    return WindowScreen(rows, choose_window(losses), 0.1, TrainOptions(epochs=6).to_dict())


def test_full_runs_that_stop_early_leave_budget_for_the_near_tied_windows():
    """ℓ = 10 and 20 are within the tolerance, 40 is not: ℓ = 10's full run ended at epoch 260
    of 600 (early), so ℓ = 20 trains fully too; after it no near tie is left."""
    screen = _screen_of({10: 0.0158, 20: 0.0161, 40: 0.05})
    assert screen.near_ties() == [10, 20] and screen.next_followup() is None  # nothing run yet
    screen = screen.with_full_run(_row(10, 0.0151, 260), 600)
    assert screen.chosen == 10 and screen.next_followup() == 20
    screen = screen.with_full_run(_row(20, 0.0097, 305), 600)
    assert (screen.chosen, screen.screened_window, screen.next_followup()) == (20, 10, None)
    assert screen.summary().startswith("window ℓ = 20 chosen on validation: the screen of 10")
    assert "kept ℓ = 10" in screen.summary()
    assert "screened" in screen.table() and "full" in screen.table()


@given(
    losses=st.dictionaries(
        st.sampled_from([10, 20, 40, 80]), st.floats(1e-6, 1.0), min_size=1, max_size=4
    ),
    runs=st.lists(st.tuples(st.integers(1, 600), st.floats(1e-6, 1.0)), max_size=4),
)
@settings(max_examples=60, deadline=None)
def test_follow_ups_stay_within_the_budget_and_the_lowest_full_run_is_chosen(losses, runs):
    """Every follow-up is a near tie not yet trained, started only while the full runs used less
    than the share of the budget; the model is the full run of lowest loss (the first on a tie)."""
    from canonid.learning.window_screen import FOLLOWUP_SHARE

    screen = _screen_of(losses)
    window = screen.chosen
    done = []
    for epochs_run, loss in runs:
        if window is None:
            break
        assert window in screen.near_ties() and window not in [r.window for r in done]
        done.append(_row(window, loss, epochs_run))
        screen = screen.with_full_run(done[-1], 600)
        assert screen.chosen == min(done, key=lambda r: r.best_val_loss).window
        window = screen.next_followup()
        if window is not None:
            assert sum(r.epochs_run for r in done) < FOLLOWUP_SHARE * 600


def test_the_near_ties_share_one_budget():
    """Follow-ups run while the full runs together used less than the profile's epochs: one
    epoch short of them leaves room for the next near tie, the whole budget does not."""
    screen = _screen_of({10: 0.0158, 20: 0.0161, 40: 0.017, 80: 0.05})
    assert screen.near_ties() == [10, 20, 40]
    assert screen.with_full_run(_row(10, 0.0151, 600), 600).next_followup() is None
    screen = screen.with_full_run(_row(10, 0.0151, 305), 600)
    assert screen.next_followup() == 20
    assert screen.with_full_run(_row(20, 0.0097, 295), 600).next_followup() is None
    screen = screen.with_full_run(_row(20, 0.0097, 294), 600)
    assert screen.next_followup() == 40
    screen = screen.with_full_run(_row(40, 0.02, 200), 600)
    assert (screen.chosen, screen.next_followup()) == (20, None)


def test_a_completed_full_run_has_no_follow_up(screened):
    """The tiny profile's 3 epochs run to the end: the screened window is the model."""
    screen = WindowScreen.read(screened)
    assert [r.window for r in screen.full_runs] == [screen.chosen] == [screen.screened_window]
    assert screen.full_runs[0].epochs_run == screen.full_epochs == 3
    assert not (screened / "followups").exists()


@pytest.fixture
def every_window_near(monkeypatch):
    """Follow-ups on the small test data: every screened window near-tied, and a full run that
    used the whole budget counted as leaving half of it (the share at 2)."""
    import canonid.learning.window_screen as ws

    monkeypatch.setattr(ws, "FOLLOWUP_SHARE", 2.0)
    monkeypatch.setattr(
        ws.WindowScreen,
        "near_ties",
        lambda self: sorted(c.window for c in self.candidates if c.best_val_loss is not None),
    )


def test_a_follow_up_run_that_validates_lower_becomes_the_model(every_window_near, data, tmp_path):
    run = tmp_path / "run"
    assert main(["train", str(data), "--out", str(run), *FAST]) == 0
    screen = WindowScreen.read(run)
    first, second = screen.full_runs  # 3 epochs, then 6 > 3 used: one follow-up
    assert first.window == screen.screened_window == 10 and second.window == 20
    assert (run / "followups" / "l20" / "weights.pt").is_file()
    best = min(screen.full_runs, key=lambda r: r.best_val_loss)
    assert screen.chosen == best.window
    assert json.loads((run / "run.json").read_text())["window"] == screen.chosen
    explicit = tmp_path / "explicit"
    argv = ["train", str(data), "--window", str(screen.chosen), "--out", str(explicit), *FAST]
    assert main(argv) == 0
    mine, theirs = weights(run), weights(explicit)
    assert all(torch.equal(mine[k], theirs[k]) for k in mine)


def test_an_interrupted_follow_up_continues_on_resume_to_the_same_bytes(
    every_window_near, data, tmp_path, monkeypatch
):
    import canonid.training as training
    from canonid.commands.benchmark import train_request

    whole = tmp_path / "whole"
    assert main(["train", str(data), "--out", str(whole), *FAST]) == 0
    train_one = training._train_one

    def interrupted(request, recipe, run_dir, **kwargs):
        if "followups" in str(run_dir):
            raise KeyboardInterrupt
        return train_one(request, recipe, run_dir, **kwargs)

    run = tmp_path / "run"
    monkeypatch.setattr(training, "_train_one", interrupted)
    with pytest.raises(KeyboardInterrupt):
        training.train(train_request([str(data), "--out", str(run), *FAST]))
    assert len(WindowScreen.read(run).full_runs) == 1  # the screened window's run is recorded
    monkeypatch.setattr(training, "_train_one", train_one)
    argv = ["train", "--resume", "--out", str(run), "--no-progress", "--threads", "1"]
    assert main(argv) == 0
    assert (run / "weights.pt").read_bytes() == (whole / "weights.pt").read_bytes()
    assert json.loads((run / "run.json").read_text())["window"] == WindowScreen.read(whole).chosen
    losses = [r.best_val_loss for r in WindowScreen.read(run).full_runs]
    assert losses == [r.best_val_loss for r in WindowScreen.read(whole).full_runs]


def test_canonid_fit_follows_up_as_the_command_line_does(every_window_near, data, tmp_path):
    import canonid

    run = tmp_path / "cli"
    assert main(["train", str(data), "--out", str(run), *FAST]) == 0
    cli = WindowScreen.read(run)
    ds = Dataset.load(data)
    options = canonid.train_options("tiny", epochs=3, device="cpu")
    api = tmp_path / "api"
    result = canonid.fit(ds.split("train"), ds.split("val"), options=options, run_dir=api)
    assert result.screen is not None and result.model.window == result.screen.chosen
    assert [(r.window, r.best_val_loss) for r in result.screen.full_runs] == [
        (r.window, r.best_val_loss) for r in cli.full_runs
    ]
    assert result.best_val_loss == min(r.best_val_loss for r in cli.full_runs)
    assert (api / "followups" / "l20" / "checkpoint.pt").is_file()
    assert WindowScreen.read(api).to_dict() == result.screen.to_dict()
