"""Model reduction: latent size, the reduced model against its formula and against the full
model, save/load/export, resume, freezing of Ĥ, refused inputs (real torch training, tiny data)."""

from __future__ import annotations

import copy
import functools

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st
from learning_helpers import damped_siso, trajectories

from canonid.kernel.canonical import cut_windows, shift_matrices
from canonid.kernel.errors import CheckpointError, ShapeError
from canonid.learning import Model, TrainOptions, fit
from canonid.learning.export import ReducedNumpyModel
from canonid.learning.nets import NotReducibleError, ReducedNet, build_net
from canonid.learning.reduction import (
    ReductionOptions,
    latent_size,
    principal_directions,
    reconstruction_mse,
    reduce_model,
)
from canonid.learning.training import CHECKPOINT_FILE, OptionError

WINDOW = 3  # dim z = 3 · (1 + 1) = 6


def options(**kw) -> TrainOptions:
    base = {
        "epochs": 100,
        "batch_size": 8,
        "lr": 3e-3,
        "horizon": 8,
        "windows_per_epoch": 32,
        "checkpoint_every": 2,
        "seed": 0,
        "device": "cpu",
    }
    return TrainOptions(**{**base, **kw})


SMALL_AE = {"encoder_hidden": (32,), "decoder_hidden": (32,)}


@pytest.fixture(scope="module")
def data():
    system = damped_siso()
    return (
        trajectories(system, 6, 40, noise=0.01, seed=10),
        trajectories(system, 2, 40, noise=0.01, seed=11),
        trajectories(system, 2, 60, noise=0.01, seed=12),
    )


@pytest.fixture(scope="module")
def full(data) -> Model:
    train, val, _ = data
    return fit(
        train, val, model="mlp", window=WINDOW, options=options(), net_options={"hidden": [16, 16]}
    ).model


def burn_in(test):
    return np.stack([t.u for t in test]), np.stack([t.y[:WINDOW] for t in test])


# ---------------------------------------------------------------------- latent size
def test_latent_size_follows_the_authors_formula():
    assert [latent_size(20, r) for r in (0.15, 0.3, 0.45, 0.6, 0.75, 0.9)] == [18, 15, 12, 9, 6, 3]
    assert latent_size(6, 0.1) == 6  # r ≤ 1 / dim z keeps every dimension
    assert latent_size(1, 0.5) == 1


@given(d=st.integers(1, 300), r=st.floats(1e-6, 1 - 1e-6))
def test_latent_size_is_between_one_and_dim_z(d, r):
    n = latent_size(d, r)
    assert 1 <= n <= d
    assert latent_size(d, min(r + 0.05, 1 - 1e-6)) <= n  # more compression, fewer states
    if r < 1 / d - 1e-9:
        assert n == d


@pytest.mark.parametrize("rate", [0.0, 1.0, 60, -0.2, float("nan")])
def test_a_rate_outside_the_open_unit_interval_is_refused(rate, full, data):
    with pytest.raises(OptionError, match="strictly between 0 and 1"):
        latent_size(6, rate)
    train, val, _ = data
    with pytest.raises(OptionError, match="strictly between 0 and 1"):
        reduce_model(full, train, val, compression=rate, options=options(epochs=1))


# ---------------------------------------------------------------------- refused models
@pytest.mark.parametrize(
    ("name", "config"),
    [("masti", {"hidden": [8]}), ("classic-gru", {})],
)
def test_only_canonical_models_can_be_reduced(name, config, full, data):
    train, val, _ = data
    net = build_net(name, window=WINDOW, n_u=1, n_y=1, **config)
    other = Model(net, full.norm)
    with pytest.raises(NotReducibleError, match=r"only canonical models can be reduced.*'mlp'"):
        reduce_model(other, train, val, compression=0.5, options=options(epochs=1))
    with pytest.raises(NotReducibleError, match=name):
        ReducedNet(regressor=name, regressor_config=net.config(), latent_dim=2, **_common(net))


def test_a_reduced_model_is_not_reduced_again(full, data):
    train, val, _ = data
    once = reduce_model(full, train, val, compression=0.5, options=options(epochs=1)).model
    with pytest.raises(NotReducibleError, match=r"got Reduced \('reduced'\)"):
        reduce_model(once, train, val, compression=0.5, options=options(epochs=1))
    with pytest.raises(NotReducibleError, match="needs a reduced model"):
        reconstruction_mse(full, data[2])


def _common(net):
    cfg = net.config()
    return {k: cfg[k] for k in ("window", "n_u", "n_y", "feedthrough", "residual")}


def test_regressor_and_reduced_model_must_agree(full):
    cfg = full.net.config()
    with pytest.raises(ShapeError, match=r"disagree on window \(3 in the regressor, 4 here\)"):
        ReducedNet(
            regressor="mlp",
            regressor_config=cfg,
            latent_dim=2,
            **{**_common(full.net), "window": 4},
        )
    with pytest.raises(OptionError, match="freeze_fraction must be in"):
        ReductionOptions(freeze_fraction=1.5)
    with pytest.raises(OptionError, match=r"unknown reduction option\(s\) \['latent'\]"):
        ReductionOptions.from_dict({"latent": 3})


# ---------------------------------------------------------------------- the reduced model
def test_identity_autoencoder_gives_the_full_model_exactly(full, data):
    """E = D = identity (one linear layer each, set by hand): x̄ = z, so the reduced model is
    the canonical model itself."""
    d = full.net.state_dim
    net = ReducedNet.around(full.net, latent_dim=d, encoder_hidden=(), decoder_hidden=())
    with torch.no_grad():
        for layer in (net.encoder[0], net.decoder[0]):
            layer.weight.copy_(torch.eye(d))
            layer.bias.zero_()
    reduced = Model(net, full.norm)
    u, y0 = burn_in(data[2])
    np.testing.assert_allclose(reduced.simulate(u, y0), full.simulate(u, y0), rtol=0, atol=1e-5)
    assert reconstruction_mse(reduced, data[2]) == pytest.approx(0.0, abs=1e-12)


def test_linear_skip_starts_from_the_principal_components(full, data):
    """With ``linear_skip`` the untrained reduced model is the PCA reduction of the training
    windows: exact at n̄ = dim z, and its reconstruction error is the PCA residual otherwise."""
    train, _, test = data
    u, y0 = burn_in(test)
    for n in (6, 4):
        mean, comps = principal_directions(full, train, n)
        net = ReducedNet.around(full.net, latent_dim=n, linear_skip=True, **SMALL_AE)
        net.init_linear(
            torch.as_tensor(mean, dtype=torch.float32), torch.as_tensor(comps, dtype=torch.float32)
        )
        reduced = Model(net, full.norm)
        z = np.concatenate(
            [cut_windows(full.norm.norm_u(t.u), full.norm.norm_y(t.y), WINDOW) for t in test]
        )
        residual = (z - mean) - (z - mean) @ comps.T @ comps
        assert reconstruction_mse(reduced, test) == pytest.approx(
            np.mean(residual**2), rel=1e-4, abs=1e-9
        )
        if n == 6:
            np.testing.assert_allclose(reduced.simulate(u, y0), full.simulate(u, y0), atol=1e-4)
    with pytest.raises(ShapeError, match="needs a reduced model built with linear_skip=True"):
        ReducedNet.around(full.net, latent_dim=4).init_linear(torch.zeros(6), torch.zeros(4, 6))


@pytest.fixture(scope="module")
def reduced_full_size(full, data):
    """Trained with n̄ = dim z and Ĥ frozen for every epoch."""
    train, val, _ = data
    return reduce_model(
        full,
        train,
        val,
        compression=0.1,
        options=options(),
        reduction=ReductionOptions(freeze_fraction=1.0, **SMALL_AE),
    )


def test_reduced_model_with_full_latent_size_follows_the_full_model(reduced_full_size, full, data):
    reduced = reduced_full_size.model
    assert reduced.net.latent_dim == full.net.state_dim == 6
    # Ĥ frozen for every epoch: the reduced model holds the full model's Ĥ unchanged
    for key, value in full.net.state_dict().items():
        assert torch.equal(reduced.net.regressor.state_dict()[key], value), key
    u, y0 = burn_in(data[2])
    pf, pr = full.simulate(u, y0), reduced.simulate(u, y0)
    assert np.mean((pr - pf) ** 2) < 0.05 * np.var(pf)  # within 5 % of the signal's variance
    untrained = Model(ReducedNet.around(full.net, latent_dim=6, **SMALL_AE), full.norm)
    assert np.mean((untrained.simulate(u, y0) - pf) ** 2) > 0.2 * np.var(pf)  # the test can fail


def test_one_step_map_is_the_formula(reduced_full_size, data):
    """x̄⁺ = E(Ā D(x̄) + B̄ u + S̄ Ĥ(D(x̄), u)), ȳ = Ĥ(D(x̄), u), computed here from E, D, Ĥ and
    the dense shift matrices, against the exported numpy callables (physical units)."""
    model = reduced_full_size.model
    exported = model.export()
    assert isinstance(exported, ReducedNumpyModel) and exported.latent_dim == 6
    net = copy.deepcopy(model.net).double()
    norm = model.norm
    rng = np.random.default_rng(0)
    x = rng.normal(size=(7, 6))
    u = rng.uniform(-1, 1, size=(7, 1))
    a_bar, b_bar, s_bar = shift_matrices(WINDOW, 1, 1)
    with torch.no_grad():
        z = net.decoder(torch.from_numpy(x)).numpy()
        un = norm.norm_u(u)
        yn = net.regressor.one_step(torch.from_numpy(z), torch.from_numpy(un)).numpy()
        z_next = z @ a_bar.T + un @ b_bar.T + yn @ s_bar.T
        x_next = net.encoder(torch.from_numpy(z_next)).numpy()
    np.testing.assert_allclose(exported.step(x, u), x_next, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(exported.output(x, u), norm.denorm_y(yn), rtol=1e-10, atol=1e-10)
    assert exported.step(x[0], u[0]).shape == (6,)

    # simulate = encode the measured burn-in window, then output / step in open loop
    tr = data[2][0]
    z0 = cut_windows(tr.u, tr.y, WINDOW)[0]  # samples 0 … ℓ−1
    state = exported.encode(z0)
    manual = []
    for t in range(WINDOW, 30):
        manual.append(exported.output(state, tr.u[t]))
        state = exported.step(state, tr.u[t])
    np.testing.assert_allclose(
        exported.simulate(tr.u[:30], tr.y[:WINDOW]), np.array(manual), rtol=1e-9, atol=1e-9
    )
    np.testing.assert_allclose(exported.H(z0, tr.u[WINDOW]), manual[0], rtol=1e-9, atol=1e-9)
    with pytest.raises(ShapeError, match=r"x must have shape \(N, 6\)"):
        exported.step(np.zeros((2, 5)), np.zeros((2, 1)))


def test_save_load_gives_the_same_rollouts(full, data, tmp_path):
    train, val, test = data
    res = reduce_model(
        full,
        train,
        val,
        compression=0.5,
        options=options(epochs=3),
        reduction=ReductionOptions(**SMALL_AE),
        run_dir=tmp_path,
    )
    loaded = Model.load(tmp_path, expect={"model": "reduced", "latent_dim": 4})
    assert isinstance(loaded.net, ReducedNet) and loaded.net.latent_dim == 4
    u, y0 = burn_in(test)
    assert np.array_equal(loaded.simulate(u, y0), res.model.simulate(u, y0))
    assert loaded.info["reduction"]["latent_dim"] == 4
    assert loaded.info["reduction"]["frozen_epochs"] == 2  # ⌊0.75 · 3⌋
    x = loaded.export().encode(cut_windows(test[0].u, test[0].y, WINDOW))
    assert x.shape == (60 - WINDOW + 1, 4)


def test_resume_ends_where_an_uninterrupted_run_ends(full, data, tmp_path):
    train, val, _ = data
    reduce = functools.partial(
        reduce_model,
        full,
        train,
        val,
        compression=0.5,
        options=options(epochs=6),
        reduction=ReductionOptions(freeze_fraction=0.5, **SMALL_AE),
    )
    whole = reduce(run_dir=tmp_path / "a")

    class Stop(Exception):
        pass

    def stop_at_5(report):
        if report.epoch == 5:
            raise Stop

    with pytest.raises(Stop):
        reduce(run_dir=tmp_path / "b", callback=stop_at_5)
    resumed = reduce(run_dir=tmp_path / "b", resume=True)
    a, b = whole.model.net.state_dict(), resumed.model.net.state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert [r["val_loss"] for r in whole.history] == [r["val_loss"] for r in resumed.history]
    # Ĥ frozen in epochs 1 … 3, trained in 4 … 6: the last weights differ from the full model's
    last = torch.load(tmp_path / "a" / CHECKPOINT_FILE, weights_only=True)["net"]
    full_weights = full.net.state_dict()
    assert any(not torch.equal(last[f"regressor.{k}"], v) for k, v in full_weights.items())
    with pytest.raises(CheckpointError, match="latent_dim: 4 there, 3 here"):
        reduce(run_dir=tmp_path / "b", resume=True, compression=0.6)


def test_gru_regressor_is_reduced_too(data):
    train, val, test = data
    gru = fit(
        train,
        val,
        model="gru",
        window=WINDOW,
        options=options(epochs=1),
        net_options={"hidden_size": 8, "num_layers": 1, "head_hidden": [8]},
    ).model
    res = reduce_model(
        gru,
        train,
        val,
        compression=0.6,
        options=options(epochs=2),
        reduction=ReductionOptions(**SMALL_AE),
    )
    assert res.model.net.latent_dim == 3  # ⌊6 · 0.4⌋ + 1
    u, y0 = burn_in(test)
    assert res.model.simulate(u, y0).shape == (2, 60 - WINDOW, 1)
    assert np.isfinite(reconstruction_mse(res.model, test))


def test_a_reduction_trains_with_subnormals_flushed_and_restores_the_default_after(data, full):
    """A reduction's auto-encoder falls into float32's subnormals without weight decay, where a
    CPU computes hundreds of times slower (the records, "Reduction: tank"): its training flushes
    them whatever the weight decay, and torch's default is back afterwards."""
    tiny = torch.finfo(torch.float32).tiny

    def subnormal_product() -> float:
        return float(torch.tensor(tiny) * torch.tensor(0.5))

    train, val, _ = data
    seen: list[float] = []
    reduce_model(
        full,
        train,
        val,
        compression=0.5,
        options=options(epochs=2),
        reduction=ReductionOptions(**SMALL_AE),
        callback=lambda report: seen.append(subnormal_product()),
    )
    assert seen and all(v == 0.0 for v in seen)
    assert subnormal_product() > 0
