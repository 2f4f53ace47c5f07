"""Output-error training: options, determinism, resume, divergence, bad input, linear oracle."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
import torch
from learning_helpers import damped_siso, damped_split, trajectories

from canonid.kernel.errors import CheckpointError, DataError, ShapeError
from canonid.learning import Model, TrainOptions, evaluate, fit
from canonid.learning.training import CHECKPOINT_FILE, OptionError

# the network options spelt out in full, so that the tests do not follow the defaults
TINY = {
    "hidden": [16, 16],
    "feedthrough": True,
    "residual": False,
    "activation": "relu",
    "linear": "off",
    "cubic": 0,
}


@pytest.fixture(scope="module")
def data():
    return damped_split()


def tiny_options(**kw) -> TrainOptions:
    base = {
        "epochs": 4,
        "batch_size": 8,
        "lr": 1e-3,
        "horizon": 8,
        "curriculum_epochs": 3,
        "windows_per_epoch": 16,
        "checkpoint_every": 2,
        "seed": 7,
        "device": "cpu",
    }
    return TrainOptions(**{**base, **kw})


def fit_tiny(train, val, **kw):
    """``fit`` of the small MLP with :func:`tiny_options` unless overridden."""
    args = {"model": "mlp", "window": 3, "options": tiny_options(), "net_options": TINY, **kw}
    return fit(train, val, **args)


def weights(model: Model) -> dict[str, np.ndarray]:
    return {k: v.numpy().copy() for k, v in model.net.state_dict().items()}


def test_curriculum_grows_the_horizon_from_one_to_its_final_value():
    opts = TrainOptions(horizon=10, curriculum_epochs=5, epochs=8)
    assert [opts.horizon_at(e) for e in range(1, 9)] == [1, 3, 5, 7, 10, 10, 10, 10]
    assert TrainOptions(horizon=10).horizon_at(1) == 10  # no curriculum
    cosine = TrainOptions(lr=1e-3, lr_final=1e-5, epochs=11)
    assert cosine.lr_at(1) == pytest.approx(1e-3) and cosine.lr_at(11) == pytest.approx(1e-5)
    assert cosine.lr_at(6) == pytest.approx((1e-3 + 1e-5) / 2)


def test_bad_options_are_named():
    with pytest.raises(OptionError, match="batch_size must be an integer >= 1"):
        TrainOptions(batch_size=0)
    with pytest.raises(OptionError, match="lr must be a positive number"):
        TrainOptions(lr=-1.0)
    with pytest.raises(OptionError, match=r"unknown training option\(s\) \['epoch'\]"):
        TrainOptions.from_dict({"epoch": 3})
    with pytest.raises(OptionError, match="device must be"):
        TrainOptions(device="tpu")


def test_same_seed_same_weights_other_seed_other_weights(data):
    train, val = data
    a = fit_tiny(train, val)
    b = fit_tiny(train, val)
    c = fit_tiny(train, val, options=tiny_options(seed=8))
    wa, wb, wc = weights(a.model), weights(b.model), weights(c.model)
    assert all(np.array_equal(wa[k], wb[k]) for k in wa)
    assert not all(np.array_equal(wa[k], wc[k]) for k in wa)
    assert [row["epoch"] for row in a.history] == [0, 1, 2, 3, 4]
    assert [row["horizon"] for row in a.history[1:]] == [1, 4, 8, 8]
    assert [r["val_loss"] for r in a.history] == [r["val_loss"] for r in b.history]


@pytest.mark.parametrize("ema_decay", [None, 0.9])
def test_best_on_validation_is_kept(data, ema_decay):
    train, val = data
    res = fit_tiny(train, val, options=tiny_options(epochs=6, ema_decay=ema_decay))
    vals = [row["val_loss"] for row in res.history]
    assert res.best_val_loss == min(vals)
    assert res.best_epoch == int(np.argmin(vals))
    from canonid.kernel.dataset import as_trajectories
    from canonid.learning.data import WindowBank
    from canonid.learning.training import validation_loss  # the kept weights reproduce it

    bank = WindowBank(as_trajectories(val), res.model.norm)
    again = validation_loss(res.model.net, bank, bank.starts(3 + 8), 8)
    assert again == pytest.approx(res.best_val_loss, rel=1e-5)


class _Interrupt(Exception):
    pass


@pytest.mark.parametrize(("name", "ema_decay"), [("mlp", None), ("masti", None), ("mlp", 0.9)])
def test_resume_ends_where_an_uninterrupted_run_ends(name, ema_decay, data, tmp_path):
    train, val = data
    kw = {
        "model": name,
        "net_options": TINY if name == "mlp" else {"hidden": [8]},
        "options": tiny_options(epochs=6, ema_decay=ema_decay),
    }
    full = fit_tiny(train, val, run_dir=tmp_path / "full", **kw)

    def stop_at_5(report):
        if report.epoch == 5:
            raise _Interrupt

    with pytest.raises(_Interrupt):
        fit_tiny(train, val, run_dir=tmp_path / "cut", callback=stop_at_5, **kw)
    # the checkpoint of epoch 4 is there; the best model so far was saved too
    assert (tmp_path / "cut" / CHECKPOINT_FILE).is_file()
    Model.load(tmp_path / "cut")
    resumed = fit_tiny(train, val, run_dir=tmp_path / "cut", resume=True, **kw)
    wf, wr = weights(full.model), weights(resumed.model)
    assert all(np.array_equal(wf[k], wr[k]) for k in wf)
    assert [r["val_loss"] for r in full.history] == [r["val_loss"] for r in resumed.history]
    assert resumed.epochs_run == 6


@pytest.mark.parametrize(("old", "path"), [(False, "off"), (True, "arx")])
def test_a_checkpoint_with_the_old_linear_spelling_resumes(data, tmp_path, old, path):
    """Checkpoints written before the linear skip said ``"linear": false`` / ``true``."""
    train, val = data
    kw = {"net_options": {**TINY, "linear": path}, "options": tiny_options(epochs=6)}

    def stop_at_5(report):
        if report.epoch == 5:
            raise _Interrupt

    with pytest.raises(_Interrupt):
        fit_tiny(train, val, run_dir=tmp_path, callback=stop_at_5, **kw)
    ckpt = tmp_path / CHECKPOINT_FILE
    state = torch.load(ckpt, weights_only=True)
    assert state["identity"]["net"]["linear"] == path
    state["identity"]["net"]["linear"] = old
    torch.save(state, ckpt)
    resumed = fit_tiny(train, val, run_dir=tmp_path, resume=True, **kw)
    assert resumed.epochs_run == 6


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"model": "masti", "net_options": {}}, r"model: 'mlp' there, 'masti' here"),
        ({"window": 4}, r"window: 3 there, 4 here"),
        ({"train_slice": slice(0, -1)}, "data"),
        ({"options": tiny_options(lr=1e-2)}, r"lr: 0\.001 there, 0\.01 here"),
        ({"run_sub": "empty"}, "no checkpoint to resume from"),
    ],
)
def test_resume_refuses_another_model_window_data_or_options(data, tmp_path, change, message):
    train, val = data
    fit_tiny(train, val, run_dir=tmp_path)
    kwargs = {k: v for k, v in change.items() if k not in ("train_slice", "run_sub")}
    run_dir = tmp_path / change.get("run_sub", "")
    with pytest.raises(CheckpointError, match=message):
        fit_tiny(
            train[change.get("train_slice", slice(None))],
            val,
            run_dir=run_dir,
            resume=True,
            **kwargs,
        )


def test_the_weight_average_follows_its_formula_and_is_what_is_kept(data, tmp_path):
    from canonid.learning.nets import build_net

    train, val = data
    # 6 trajectories × 2 windows in one batch of 16: one optimiser step
    opts = tiny_options(epochs=1, batch_size=16, ema_decay=0.5)
    res = fit_tiny(train, val, options=opts, run_dir=tmp_path)
    ckpt = torch.load(tmp_path / CHECKPOINT_FILE, weights_only=True)
    torch.manual_seed(opts.seed)  # the untrained network, built as fit builds it
    w0 = dict(build_net("mlp", window=3, n_u=1, n_y=1, **TINY).named_parameters())
    # step 0 of the average: decay min(0.5, 1/10) = 0.1
    for k, w1 in ckpt["net"].items():
        if k in w0:
            expected = 0.1 * w0[k].detach() + 0.9 * w1
            torch.testing.assert_close(ckpt["ema"][k], expected, rtol=1e-6, atol=1e-7)
    assert ckpt["ema_steps"] == 1
    kept = weights(res.model)
    assert res.best_epoch == 1  # the average, not the network's last weights, was kept
    assert all(np.array_equal(kept[k], ckpt["ema"][k].numpy()) for k in ckpt["ema"])
    assert not all(np.array_equal(kept[k], ckpt["net"][k].numpy()) for k in ckpt["ema"])
    with pytest.raises(OptionError, match=r"ema_decay must be None or in \(0, 1\)"):
        TrainOptions(ema_decay=1.0)


def test_resume_with_more_epochs_continues_the_run(data, tmp_path):
    train, val = data
    fit_tiny(train, val, run_dir=tmp_path)
    longer = fit_tiny(train, val, options=tiny_options(epochs=5), run_dir=tmp_path, resume=True)
    assert longer.epochs_run == 5 and len(longer.history) == 6


def test_a_run_that_stopped_early_resumes_to_the_same_end(data, tmp_path):
    train, val = data
    # a learning rate too large to improve for long: validation stalls, patience 2 ends it
    opts = tiny_options(epochs=40, lr=0.3, patience=2)
    ended = fit_tiny(train, val, options=opts, run_dir=tmp_path)
    assert ended.stopped == "early_stopping" and ended.epochs_run < 40
    again = fit_tiny(train, val, options=opts, run_dir=tmp_path, resume=True)
    assert again.stopped == "early_stopping" and again.epochs_run == ended.epochs_run
    assert again.history == ended.history
    wa, wb = weights(ended.model), weights(again.model)
    assert all(np.array_equal(wa[k], wb[k]) for k in wa)
    # a larger patience, given on resume, lets it go on
    longer = fit_tiny(
        train,
        val,
        options=tiny_options(epochs=40, lr=0.3, patience=50),
        run_dir=tmp_path,
        resume=True,
    )
    assert longer.epochs_run == 40


def test_a_diverging_run_stops_and_keeps_the_best_model(data, monkeypatch, caplog):
    from canonid.learning.nets.ours_mlp import OursMLP

    train, val = data
    calls = {"n": 0}
    original = OursMLP.training_loss

    def poisoned(self, u, y, *, alpha_first):
        calls["n"] += 1
        loss, parts = original(self, u, y, alpha_first=alpha_first)
        return (loss * math.nan if calls["n"] > 4 else loss), parts

    monkeypatch.setattr(OursMLP, "training_loss", poisoned)
    res = fit_tiny(train, val, options=tiny_options(epochs=10))
    assert res.stopped == "diverged"
    assert res.epochs_run < 10
    assert math.isfinite(res.best_val_loss)
    assert all(torch.isfinite(p).all() for p in res.model.net.parameters())
    assert "not finite" in caplog.text


def test_a_transient_non_finite_loss_is_recovered_from(data, monkeypatch, caplog, tmp_path):
    """One blown-up batch: back to the best weights, half the learning rate, training goes on;
    the recovery survives a resume."""
    from canonid.learning.nets import OursMLP

    train, val = data
    original = OursMLP.training_loss
    calls = {"n": 0}

    def once(self, u, y, *, alpha_first):
        calls["n"] += 1
        loss, parts = original(self, u, y, alpha_first=alpha_first)
        return (loss * math.nan if calls["n"] == 3 else loss), parts

    monkeypatch.setattr(OursMLP, "training_loss", once)
    res = fit_tiny(train, val, options=tiny_options(epochs=4), run_dir=tmp_path)
    assert res.stopped == "completed" and res.epochs_run == 4
    assert "recovery 1 of 5" in caplog.text
    lrs = [row["lr"] for row in res.history[1:]]
    assert lrs[-1] == pytest.approx(0.5 * tiny_options().lr_at(4))
    ckpt = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    assert (ckpt["lr_scale"], ckpt["recoveries"]) == (0.5, 1)


def test_early_stopping_after_the_curriculum(data):
    train, val = data
    res = fit(
        train,
        val,
        model="mlp",
        window=3,
        options=tiny_options(epochs=200, lr=1e-9, patience=3, curriculum_epochs=2),
        net_options=TINY,
    )
    assert res.stopped == "early_stopping"
    assert res.epochs_run < 200


def test_validation_shorter_than_its_rollout_is_cut_to_fit_and_recorded(data, caplog):
    train, val = data  # validation trajectories of 40 samples: 37 steps after ℓ = 3
    with caplog.at_level(logging.WARNING, logger="canonid.learning.training"):
        res = fit_tiny(train, val, options=tiny_options(val_horizon=39))
    assert "validation rollouts cut from 39 to 37 steps" in caplog.text
    assert res.model.info["training"]["options"]["val_horizon"] == 37
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="canonid.learning.training"):
        fit_tiny(train, val, options=tiny_options(val_horizon=37))
    assert "cut" not in caplog.text  # a rollout that fits is left alone


def test_bad_input_is_refused_with_a_clear_error(data):
    train, val = data
    short = [type(train[0])(u=train[0].u[:3], y=train[0].y[:3])]
    with pytest.raises(ShapeError, match=r"trajectory 0: has 3 samples; window ℓ = 3"):
        fit_tiny(short, val)
    mismatched = [type(train[0])(u=train[0].u, y=train[0].y[:-1])]
    with pytest.raises(ShapeError, match="u has 40 samples but y has 39"):
        fit_tiny(mismatched, val)
    nan = [type(train[0])(u=train[0].u, y=train[0].y.copy())]
    nan[0].y[5, 0] = np.nan
    with pytest.raises(
        ShapeError, match=r"training data, trajectory 0: field .y. contains 1 non-finite"
    ):
        fit_tiny(nan, val)
    with pytest.raises(ShapeError, match="needs trajectories of at least 103"):
        fit_tiny(train, val, options=tiny_options(horizon=100))
    with pytest.raises(DataError, match="no trajectories"):
        fit_tiny([], val)
    with pytest.raises(OptionError, match="CUDA is not available"):
        if torch.cuda.is_available():
            raise OptionError("CUDA is not available (skipped: a GPU is present)")
        fit_tiny(train, val, options=tiny_options(device="cuda"))


@pytest.mark.slow
def test_mlp_on_a_linear_system_reaches_the_noise_level():
    """Ours (MLP), quick profile shortened to 30 epochs of 30-step rollouts, on a damped
    linear system: the 100-step rollout MSE is within 2× the noise variance of the measured
    outputs, and below it against the noise-free outputs."""
    from canonid.profiles import train_options

    system = damped_siso()
    noise = 0.05  # uniform in [−noise, noise]: variance noise²/3
    train = trajectories(system, 20, 200, noise=noise, seed=1)
    val = trajectories(system, 5, 200, noise=noise, seed=2)
    test = trajectories(system, 5, 200, noise=noise, seed=3)
    opts = train_options("quick", epochs=30, horizon=30, val_horizon=100, device="cpu")
    res = fit(train, val, model="mlp", window=4, options=opts, net_options={"residual": True})
    scores = evaluate(res.model, test, horizon=100)
    noise_var = noise**2 / 3
    assert scores.measured.rollout_mse < 2 * noise_var
    assert scores.clean is not None and scores.clean.rollout_mse < noise_var
