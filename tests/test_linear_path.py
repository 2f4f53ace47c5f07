"""The affine path of the canonical models, its least-squares (ARX) start, the ARX model, the
sample-based epoch and the named option sets (defaults, the paper's)."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from learning_helpers import damped_siso, trajectories

from canonid.kernel.canonical import cut_windows
from canonid.kernel.dataset import Trajectory, as_trajectories
from canonid.learning import NETS, TrainOptions, evaluate, fit
from canonid.learning.data import Normalisation
from canonid.learning.linear import feedthrough_test, least_squares, regressors
from canonid.learning.nets.base import LINEAR_PATHS, linear_path
from canonid.learning.presets import DEFAULT_NET_OPTIONS, PAPER_NET_OPTIONS, net_options
from canonid.learning.search import Search
from canonid.learning.training import _draw_windows

# the damped system's transfer function: y_t = a1 y_{t−1} + a2 y_{t−2} + b1 u_{t−1} + b2 u_{t−2}
# with a1 = tr A, a2 = −det A, b1 = C B, b2 = C A B − a1 C B (A, B, C of damped_siso)
A1, A2, B1, B2 = 1.6, -0.68, 0.5, -0.2


def options(**kw) -> TrainOptions:
    base = {
        "epochs": 3,
        "batch_size": 16,
        "lr": 1e-3,
        "horizon": 20,
        "windows_per_epoch": 64,
        "val_stride": 5,
        "seed": 0,
        "device": "cpu",
        "checkpoint_every": 100,
    }
    return TrainOptions(**{**base, **kw})


def test_the_regression_rows_are_the_canonical_windows():
    tr = trajectories(damped_siso(), 1, 30, noise=0.01, seed=4)[0]
    norm = Normalisation.fit(as_trajectories([tr]))
    x, y, y_prev = regressors(as_trajectories([tr]), norm, window=3, feedthrough=True)
    z = cut_windows(norm.norm_u(tr.u), norm.norm_y(tr.y), 3)[:-1]  # z_t for t = 3 … T−1
    np.testing.assert_array_equal(x[:, :-1], z)
    np.testing.assert_array_equal(x[:, -1:], norm.norm_u(tr.u)[3:])
    np.testing.assert_array_equal(y, norm.norm_y(tr.y)[3:])
    np.testing.assert_array_equal(y_prev, norm.norm_y(tr.y)[2:-1])


@pytest.mark.parametrize("residual", [False, True])
def test_the_least_squares_start_is_the_systems_arx_model(residual):
    """Noise-free data of a second-order system: the fit recovers its difference equation."""
    data = as_trajectories(trajectories(damped_siso(), 4, 80, noise=0.0, seed=1))
    norm = Normalisation.fit(data)
    scale = norm.dy_std / norm.y_std if residual else None
    L, c = least_squares(data, norm, window=2, feedthrough=False, residual_scale=scale)
    # back to physical units: z = (u_{t−2}, y_{t−2}, u_{t−1}, y_{t−1})
    su, sy, mu, my = norm.u_std[0], norm.y_std[0], norm.u_mean[0], norm.y_mean[0]
    row = L[0] * (scale[0] if residual else 1.0)
    if residual:
        row = row + np.array([0, 0, 0, 1.0])  # y_t = y_{t−1} + s · raw
    coef = row * sy / np.array([su, sy, su, sy])
    np.testing.assert_allclose(coef, [B2, A2, B1, A1], atol=1e-8)
    offset = sy * (c[0] * (scale[0] if residual else 1.0)) + my - coef @ [mu, my, mu, my]
    assert abs(offset) < 1e-8


def test_the_arx_model_takes_no_gradient_step_and_holds_the_least_squares_fit(tmp_path):
    data = trajectories(damped_siso(), 6, 80, noise=0.0, seed=2)
    train, val = data[:4], data[4:]
    res = fit(train, val, model="arx", window=2, options=options(), run_dir=tmp_path)
    assert res.stopped == "least_squares" and res.epochs_run == 0
    assert [row["epoch"] for row in res.history] == [0]
    L, c = least_squares(as_trajectories(train), res.model.norm, window=2, feedthrough=False)
    affine = res.model.net.affine
    np.testing.assert_allclose(affine.weight.detach().numpy(), L, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(affine.bias.detach().numpy(), c, rtol=1e-5, atol=1e-6)
    # on noise-free data of an order-2 system the simulation is exact (float32 weights)
    tr = val[0]
    sim = res.model.simulate(tr.u, tr.y[:2])
    np.testing.assert_allclose(sim, tr.y[2:], atol=1e-4)
    assert (tmp_path / "checkpoint.pt").is_file()


def test_training_starts_from_the_arx_model():
    """Epoch 0 of Ours (MLP) with the affine path scores exactly what the ARX model scores."""
    data = trajectories(damped_siso(), 8, 100, noise=0.02, seed=3)
    train, val = data[:6], data[6:]
    common = {"residual": False, "feedthrough": False, "linear": True}
    mlp = fit(train, val, model="mlp", window=3, options=options(epochs=1), net_options=common)
    arx = fit(train, val, model="arx", window=3, options=options(epochs=1), net_options=common)
    assert mlp.history[0]["val_loss"] == pytest.approx(arx.history[0]["val_loss"], rel=1e-5)


def test_the_linear_path_reaches_the_noise_floor_of_linear_data_in_a_few_epochs():
    noise = 0.05  # uniform: variance noise² / 3
    system = damped_siso()
    train = trajectories(system, 10, 150, noise=noise, seed=5)
    val = trajectories(system, 3, 150, noise=noise, seed=6)
    test = trajectories(system, 3, 150, noise=noise, seed=7)
    res = fit(
        train,
        val,
        model="mlp",
        window=4,
        options=options(epochs=3),
        net_options={"hidden": [32], "linear": True},
    )
    scores = evaluate(res.model, test, horizon=50)
    assert scores.measured.rollout_mse < 1.5 * noise**2 / 3


def test_one_record_or_ten_experiments_get_the_same_budget_and_error(monkeypatch):
    """The same samples as one record or cut into ten: the same optimiser steps, and the best
    validation errors within 10 % of each other."""
    system = damped_siso()
    whole = trajectories(system, 1, 1500, noise=0.02, seed=8)[0]
    pieces = [
        SimpleNamespace(u=whole.u[k : k + 150], y=whole.y[k : k + 150]) for k in range(0, 1500, 150)
    ]
    val = trajectories(system, 3, 150, noise=0.02, seed=9)
    steps = {"n": 0}
    original = torch.optim.Adam.step

    def counted(self, *args, **kw):
        steps["n"] += 1
        return original(self, *args, **kw)

    monkeypatch.setattr(torch.optim.Adam, "step", counted)
    results = {}
    for name, train in (("record", [whole]), ("experiments", pieces)):
        steps["n"] = 0
        res = fit(
            train,
            val,
            model="mlp",
            window=3,
            options=options(epochs=4),
            net_options={"linear": True, "cubic": 0},  # the cubic test would add its own steps
        )
        results[name] = (steps["n"], res.best_val_loss)
    assert results["record"][0] == results["experiments"][0] == 4 * 64 // 16
    a, b = results["record"][1], results["experiments"][1]
    assert abs(a - b) <= 0.1 * max(a, b)


@settings(max_examples=50, deadline=None)
@given(
    lengths=st.lists(st.integers(1, 60), min_size=1, max_size=8),
    span=st.integers(1, 20),
    k=st.integers(1, 200),
    seed=st.integers(0, 2**16),
)
def test_window_draws_fit_their_trajectory(lengths, span, k, seed):
    if max(lengths) < span:
        return
    draws = _draw_windows(np.random.default_rng(seed), lengths, span, k)
    assert draws.shape == (k, 2)
    for traj, start in draws:
        assert 0 <= start and start + span <= lengths[traj]


def test_window_draws_are_uniform_over_the_starts():
    """A trajectory with three times the starts gets about three times the windows."""
    draws = _draw_windows(np.random.default_rng(0), [40, 20, 5], 11, 30_000)
    counts = np.bincount(draws[:, 0], minlength=3) / 30_000
    np.testing.assert_allclose(counts, [30 / 40, 10 / 40, 0.0], atol=0.01)


def test_validation_is_capped_by_a_seeded_subset():
    from canonid.learning.data import WindowBank
    from canonid.learning.training import _validation_starts

    tr = trajectories(damped_siso(), 2, 400, noise=0.0, seed=1)
    series = as_trajectories(tr)
    bank = WindowBank(series, Normalisation.fit(series))
    full = _validation_starts(bank, 30, options())
    capped = _validation_starts(bank, 30, options(val_windows=20))
    assert len(full) > 20 and len(capped) == 20
    assert {tuple(r) for r in capped} <= {tuple(r) for r in full}
    np.testing.assert_array_equal(capped, _validation_starts(bank, 30, options(val_windows=20)))


def test_option_sets_are_named_once():
    assert net_options("mlp") == DEFAULT_NET_OPTIONS["mlp"]
    assert net_options("mlp", paper=True) == PAPER_NET_OPTIONS["mlp"]
    assert net_options("mlp", {"linear": "off"})["linear"] == "off"
    assert net_options("classic-gru") == {}
    # the authors' code: increment output, no feedthrough, ReLU, 3 × 256, no affine path, no
    # cubic branch
    assert PAPER_NET_OPTIONS["mlp"] == {
        "hidden": [256, 256, 256],
        "activation": "relu",
        "residual": True,
        "feedthrough": False,
        "linear": "off",
        "cubic": 0,
    }


@pytest.mark.parametrize("value", [*LINEAR_PATHS, False, True])
def test_every_linear_path_builds_and_round_trips_its_config(value):
    """``False`` / ``True`` (configurations written before the skip existed) read as off / arx;
    the path exists unless it is off, and ``config()`` rebuilds the same network."""
    net = NETS["mlp"](window=3, n_u=1, n_y=2, hidden=[8], linear=value)
    name = linear_path(value)
    assert net.linear == name and name in LINEAR_PATHS
    assert (net.affine is None) == (name == "off")
    again = NETS["mlp"](**net.config())
    assert again.config() == net.config()
    assert {k for k, _ in again.named_parameters()} == {k for k, _ in net.named_parameters()}


def test_an_unknown_linear_path_is_refused_by_name():
    from canonid.kernel.errors import ShapeError

    with pytest.raises(ShapeError, match="linear must be one of off, skip, arx, got 'lsq'"):
        NETS["mlp"](window=3, n_u=1, n_y=1, linear="lsq")


def test_the_skip_keeps_its_random_start_and_the_arx_path_starts_at_least_squares():
    """``"arx"`` starts the affine layer at the ARX fit and the network's last layer at zero;
    ``"skip"`` starts the affine layer at zero and the network as built."""
    data = trajectories(damped_siso(), 8, 100, noise=0.02, seed=3)
    train, val = data[:6], data[6:]
    common = {"residual": False, "feedthrough": False, "hidden": [16]}
    epoch0 = options(epochs=1, lr=1e-12)  # Adam moves each weight by about lr: the start
    fitted = {
        path: fit(
            train,
            val,
            model="mlp",
            window=3,
            options=epoch0,
            net_options={**common, "linear": path},
        ).model.net
        for path in ("skip", "arx")
    }
    series = as_trajectories(train)
    L, c = least_squares(series, Normalisation.fit(series), window=3, feedthrough=False)
    arx, skip = fitted["arx"], fitted["skip"]
    np.testing.assert_allclose(arx.affine.weight.detach().numpy(), L, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(arx.affine.bias.detach().numpy(), c, rtol=1e-5, atol=1e-6)
    assert not arx.output_layer().weight.detach().any()
    assert skip.affine.weight.detach().abs().max() < 1e-9
    assert skip.affine.bias.detach().abs().max() < 1e-9
    assert skip.output_layer().weight.detach().abs().min() > 1e-9


def test_an_old_run_option_is_refused_by_name():
    from canonid.learning import OptionError

    with pytest.raises(OptionError, match="windows_per_trajectory was replaced by windows_per"):
        TrainOptions.from_dict({"windows_per_trajectory": 4})


def test_cli_defaults_and_paper_options_are_recorded(tmp_path, capsys):
    """`canonid train` without model options gets the defaults; `--paper-options` the paper's
    model exactly; both are written to config.json."""
    from canonid.cli import main

    data = trajectories(damped_siso(), 6, 120, noise=0.01, seed=10)
    np.savez(
        tmp_path / "data.npz",
        u=np.stack([t.u for t in data]),
        y=np.stack([t.y for t in data]),
        dt=1.0,
    )
    common = [str(tmp_path / "data.npz"), "--window", "3", "--epochs", "1", "--no-progress"]
    common += ["--device", "cpu", "--train-horizon", "10"]
    assert main(["train", *common, "--model", "mlp", "--out", str(tmp_path / "d")]) == 0
    assert "feedthrough off (decided on validation" in capsys.readouterr().out
    config = json.loads((tmp_path / "d" / "config.json").read_text())
    net, decided = config["net"], config["info"]["feedthrough_test"]
    # feedthrough "auto" is recorded as what its test decided, cubic "auto" as what the search
    # chose (a network without the cubic branch does not name it)
    cubic = Search.read(tmp_path / "d").chosen.cubic
    expected = {**DEFAULT_NET_OPTIONS["mlp"], "feedthrough": decided["feedthrough"], "cubic": cubic}
    assert {k: net.get(k, 0) for k in DEFAULT_NET_OPTIONS["mlp"]} == expected
    assert decided["feedthrough"] is False  # the damped system has no direct term
    assert (
        main(["train", *common, "--model", "mlp", "--paper-options", "--out", str(tmp_path / "p")])
        == 0
    )
    net = json.loads((tmp_path / "p" / "config.json").read_text())["net"]
    assert {k: net.get(k, 0) for k in PAPER_NET_OPTIONS["mlp"]} == PAPER_NET_OPTIONS["mlp"]
    assert not (tmp_path / "p" / "search.json").exists()  # the paper's model: nothing searched
    out = tmp_path / "a"
    assert main(["train", *common, "--model", "arx", "--out", str(out)]) == 0
    assert "arx: least_squares after 0 epochs" in capsys.readouterr().out
    assert (out / "metrics.json").is_file()
    assert (
        main(["train", *common, "--model", "arx", "--no-linear", "--out", str(tmp_path / "x")]) == 1
    )
    assert "ARX is the affine path alone" in capsys.readouterr().err
    # --linear arx is the ARX start, --linear skip the skip, --no-linear none
    forms = ((["--linear", "arx"], "arx"), (["--linear", "skip"], "skip"), (["--no-linear"], "off"))
    for flags, path in forms:
        out = tmp_path / f"lin-{path}"
        argv = ["train", *common, "--model", "mlp", *flags, "--out", str(out)]
        assert main(argv) == 0
        assert json.loads((out / "config.json").read_text())["net"]["linear"] == path
    resume = ["train", "--resume", "--out", str(tmp_path / "d"), "--no-progress", "--device", "cpu"]
    assert main([*resume, "--no-linear"]) == 1
    assert "--linear cannot change when resuming" in capsys.readouterr().err


def test_reproduce_trains_the_papers_model_and_canonids_beside_it(tmp_path):
    from canonid.reproduce import plan_jobs, settings_from_profile

    settings_ = settings_from_profile("tiny", out=tmp_path)
    info = SimpleNamespace(path=tmp_path / "data", checksum="0")
    jobs = plan_jobs(settings_, {s: info for s in settings_.systems})
    mlp = [j for j in jobs if getattr(j, "model", None) == "mlp"]
    paper = [j for j in mlp if j.options == "paper"]
    assert paper and all(j.net_options == PAPER_NET_OPTIONS["mlp"] for j in paper)
    defaults = [j for j in mlp if j.options == "defaults"]
    assert defaults and all(j.net_options == DEFAULT_NET_OPTIONS["mlp"] for j in defaults)


def _first_order(direct: float, delayed: float, *, seed: int, n: int = 3, T: int = 300):
    """``y_t = 0.8 y_{t−1} + direct·u_t + delayed·u_{t−1} + noise`` records, white input."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        u = rng.uniform(-1, 1, T)
        y = np.zeros(T)
        for t in range(1, T):
            y[t] = 0.8 * y[t - 1] + direct * u[t] + delayed * u[t - 1]
        y += 0.01 * rng.standard_normal(T)
        out.append(Trajectory(u=u[:, None], y=y[:, None]))
    return out


@pytest.mark.parametrize(("direct", "delayed", "expected"), [(0.5, 0.0, True), (0.0, 0.5, False)])
def test_feedthrough_auto_finds_a_direct_term_and_only_then(direct, delayed, expected):
    train, val = _first_order(direct, delayed, seed=1), _first_order(direct, delayed, seed=2)
    test = feedthrough_test(train, val, Normalisation.fit(train), window=3)
    assert test.feedthrough is expected
    # with a direct term u_t explains nearly all of the one-step error; without, nothing
    assert (
        (test.with_u / test.without_u < 0.1) if expected else (test.with_u / test.without_u > 0.9)
    )


def test_fit_with_feedthrough_auto_records_its_decision():
    train, val = _first_order(0.5, 0.0, seed=1), _first_order(0.5, 0.0, seed=2)
    opts = TrainOptions(epochs=1, batch_size=8, horizon=4, windows_per_epoch=8, device="cpu")
    result = fit(
        train,
        val,
        window=3,
        options=opts,
        net_options={"feedthrough": "auto", "hidden": [8]},
    )
    assert result.model.net.feedthrough is True
    assert result.model.info["feedthrough_test"]["feedthrough"] is True


def test_regressors_with_a_stride_are_every_kth_row_of_each_trajectory():
    data = _first_order(0.5, 0.2, seed=3, n=2, T=50)
    norm = Normalisation.fit(data)
    full = [regressors([tr], norm, window=4, feedthrough=True) for tr in data]
    strided = regressors(data, norm, window=4, feedthrough=True, stride=3)
    for a, b in zip(strided, (np.concatenate([f[i][::3] for f in full]) for i in range(3))):
        np.testing.assert_array_equal(a, b)
