"""The four models behind one interface, parametrised over the registry."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from learning_helpers import damped_siso, trajectories

from canonid.kernel.canonical import cut_windows
from canonid.kernel.canonical import shift as np_shift
from canonid.kernel.dataset import as_trajectories
from canonid.kernel.errors import CheckpointError, ShapeError
from canonid.learning import Model, Normalisation, build_net, model_names
from canonid.learning.canonical import pairs_to_state
from canonid.learning.nets import CanonicalModel, UnknownModelError
from canonid.models.linear import linear_example

SMALL = {
    "mlp": {"hidden": [16, 16]},
    "gru": {"hidden_size": 8, "num_layers": 2, "head_hidden": [8]},
    "classic-gru": {},
    "masti": {"hidden": [16]},
    "arx": {},
}


def small_net(name: str, *, window: int = 3, n_u: int = 1, n_y: int = 1, seed: int = 0, **kw):
    torch.manual_seed(seed)
    return build_net(name, window=window, n_u=n_u, n_y=n_y, **SMALL[name], **kw)


def small_model(name: str, data, *, window: int = 3, seed: int = 0, **kw) -> Model:
    series = as_trajectories(data)
    net = small_net(
        name, window=window, n_u=series[0].u.shape[1], n_y=series[0].y.shape[1], seed=seed, **kw
    )
    return Model(net, Normalisation.fit(series))


@pytest.fixture(scope="module")
def siso_data():
    return trajectories(damped_siso(), 4, 40, noise=0.01, seed=1)


@pytest.fixture(scope="module")
def mimo_data():
    return trajectories(linear_example("linear-mimo"), 3, 30, noise=0.01, seed=2)


def batch(data, window: int, horizon: int, norm: Normalisation):
    u = np.stack([norm.norm_u(tr.u[s : s + window + horizon]) for tr in data for s in (0, 5)])
    y = np.stack([norm.norm_y(tr.y[s : s + window + horizon]) for tr in data for s in (0, 5)])
    return torch.tensor(u, dtype=torch.float32), torch.tensor(y, dtype=torch.float32)


def test_registry_lists_the_models_in_table_order():
    assert model_names() == ["mlp", "gru", "classic-gru", "masti", "arx"]
    with pytest.raises(UnknownModelError, match="unknown model 'lstm'"):
        build_net("lstm", window=2, n_u=1, n_y=1)
    with pytest.raises(UnknownModelError, match="bad configuration"):
        build_net("mlp", window=2, n_u=1, n_y=1, widths=[3])
    with pytest.raises(ShapeError, match="window must be an integer >= 1"):
        build_net("mlp", window=0, n_u=1, n_y=1)


def test_paper_sizes_are_the_defaults():
    mlp = build_net("mlp", window=10, n_u=1, n_y=1)
    assert mlp.config()["hidden"] == [256, 256, 256]
    gru = build_net("gru", window=10, n_u=1, n_y=1)
    assert (gru.hidden_size, gru.num_layers) == (128, 3)
    classic = build_net("classic-gru", window=10, n_u=1, n_y=1)
    assert (classic.hidden_size, classic.num_layers, classic.head_hidden) == (10, 2, 10)
    odd = build_net("classic-gru", window=5, n_u=2, n_y=3)
    assert odd.hidden_size == 13  # ⌈5·5/2⌉
    assert build_net("mlp", window=10, n_u=1, n_y=1).feedthrough is True


@pytest.mark.parametrize("name", model_names())
def test_one_training_step_lowers_the_loss_on_a_fixed_batch(name, mimo_data):
    norm = Normalisation.fit(as_trajectories(mimo_data))
    net = small_net(name, n_u=2, n_y=2)
    u, y = batch(mimo_data, 3, 6, norm)
    opt = torch.optim.Adam(net.parameters(), lr=1e-4)
    before, parts = net.training_loss(u, y, alpha_first=10.0)
    assert "output_error" in parts
    opt.zero_grad()
    before.backward()
    before = before.detach()
    opt.step()
    after, _ = net.training_loss(u, y, alpha_first=10.0)
    assert after.item() < before.item()


@pytest.mark.parametrize("name", model_names())
def test_first_rollout_step_is_the_one_step_map(name, mimo_data):
    norm = Normalisation.fit(as_trajectories(mimo_data))
    net = small_net(name, n_u=2, n_y=2).eval()
    u, y = batch(mimo_data, 3, 4, norm)
    with torch.no_grad():
        pred = net.rollout(u[:, :3], y[:, :3], u[:, 3:])
        first = net.one_step(pairs_to_state(u[:, :3], y[:, :3]), u[:, 3])
    assert pred.shape == (u.shape[0], 4, 2)
    torch.testing.assert_close(pred[:, 0], first, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("name", ["mlp", "gru"])
def test_canonical_simulation_is_the_shift_recursion_of_H(name, mimo_data):
    """simulate == ẑ_{t+1} = Ā ẑ_t + B̄ u_t + S̄ H(ẑ_t, u_t) written out with the numpy reference."""
    model = small_model(name, mimo_data)
    assert isinstance(model.net, CanonicalModel)
    exported = model.export()
    tr = mimo_data[0]
    ell, T = 3, 15
    sim = exported.simulate(tr.u[:T], tr.y[:ell])
    z = cut_windows(tr.u[:ell], tr.y[:ell], ell)[0]
    manual = []
    for t in range(ell, T):
        y_t = exported.H(z, tr.u[t])
        manual.append(y_t)
        z = np_shift(z, tr.u[t], y_t)
    np.testing.assert_allclose(sim, np.array(manual), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("name", model_names())
def test_export_is_plain_numpy_and_matches_the_model(name, mimo_data):
    model = small_model(name, mimo_data)
    exported = model.export()
    assert (exported.window, exported.n_u, exported.n_y, exported.name) == (3, 2, 2, name)
    tr = mimo_data[1]
    Z = cut_windows(tr.u, tr.y, 3)[:-1]  # z_t for t = 3 … T−1
    y_hat = exported.H(Z, tr.u[3:])
    assert isinstance(y_hat, np.ndarray) and y_hat.dtype == np.float64
    assert y_hat.shape == (len(Z), 2)
    np.testing.assert_allclose(exported.H(Z[4], tr.u[7]), y_hat[4], rtol=1e-12)
    # H is the first step of every simulation from the same window
    sims = exported.simulate(
        np.stack([tr.u[k : k + 5] for k in range(4)]), np.stack([tr.y[k : k + 3] for k in range(4)])
    )
    np.testing.assert_allclose(sims[:, 0], y_hat[:4], rtol=1e-9, atol=1e-9)
    # float64 export vs the float32 model
    np.testing.assert_allclose(
        model.simulate(tr.u, tr.y[:3]), exported.simulate(tr.u, tr.y[:3]), rtol=1e-3, atol=1e-3
    )
    with pytest.raises(ShapeError, match="H expects z"):
        exported.H(Z[:, :-1], tr.u[3:])


@pytest.mark.parametrize("name", model_names())
def test_save_load_gives_identical_predictions(name, mimo_data, tmp_path):
    model = small_model(name, mimo_data, seed=3)
    model.net.residual_scale.fill_(0.5)
    tr = mimo_data[2]
    before = model.simulate(tr.u, tr.y[:3])
    model.save(tmp_path / "m")
    loaded = Model.load(tmp_path / "m", expect={"model": name, "window": 3})
    np.testing.assert_array_equal(loaded.simulate(tr.u, tr.y[:3]), before)
    assert loaded.net.config() == model.net.config()
    np.testing.assert_array_equal(loaded.norm.y_std, model.norm.y_std)


@pytest.mark.parametrize("activation", ["tanh", "silu"])
def test_the_mlp_activation_is_built_saved_and_loaded(activation, mimo_data, tmp_path):
    model = small_model("mlp", mimo_data, seed=4, activation=activation)
    kinds = {type(m).__name__.lower() for m in model.net.net}
    assert kinds == {"linear", activation}
    tr = mimo_data[0]
    before = model.simulate(tr.u, tr.y[:3])
    model.save(tmp_path / "m")
    loaded = Model.load(tmp_path / "m")
    assert loaded.net.config()["activation"] == activation
    np.testing.assert_array_equal(loaded.simulate(tr.u, tr.y[:3]), before)
    with pytest.raises(UnknownModelError, match=r"activation must be one of \['relu', 'silu'"):
        build_net("mlp", window=2, n_u=1, n_y=1, activation="gelu")


def test_loading_another_model_or_window_names_what_differs(mimo_data, tmp_path):
    small_model("mlp", mimo_data).save(tmp_path / "mlp")
    with pytest.raises(CheckpointError, match=r"model: 'mlp' there, 'gru' here"):
        Model.load(tmp_path / "mlp", expect={"model": "gru"})
    with pytest.raises(CheckpointError, match=r"window: 3 there, 5 here"):
        Model.load(tmp_path / "mlp", expect={"window": 5})
    # weights of a window-5 network under a window-3 configuration
    other = small_model("mlp", mimo_data, window=5)
    torch.save(other.net.state_dict(), tmp_path / "mlp" / "weights.pt")
    with pytest.raises(CheckpointError, match=r"shape differs: net\.0\.weight"):
        Model.load(tmp_path / "mlp")
    (tmp_path / "mlp" / "weights.pt").write_bytes(b"not a torch file")
    with pytest.raises(CheckpointError, match="cannot read weights"):
        Model.load(tmp_path / "mlp")


@pytest.mark.parametrize("name", model_names())
def test_without_feedthrough_the_output_ignores_u_t(name, siso_data):
    net = small_net(name, feedthrough=False).eval()
    z = torch.randn(5, 6)
    with torch.no_grad():
        a = net.one_step(z, torch.zeros(5, 1))
        b = net.one_step(z, torch.full((5, 1), 7.0))
    torch.testing.assert_close(a, b)
    with torch.no_grad():
        c = small_net(name, feedthrough=True).eval().one_step(z, torch.full((5, 1), 7.0))
        d = small_net(name, feedthrough=True).eval().one_step(z, torch.zeros(5, 1))
    assert not torch.allclose(c, d)


@pytest.mark.parametrize("name", model_names())
def test_residual_adds_the_scaled_increment_to_the_last_output(name):
    net = small_net(name, residual=True).eval()
    net.residual_scale.fill_(0.25)
    last = [m for m in net.modules() if isinstance(m, torch.nn.Linear)][-1]
    z = torch.randn(4, 6)
    u = torch.randn(4, 1)
    with torch.no_grad():
        raw_bias = last.bias.clone()
        last.weight.zero_()
        y = net.one_step(z, u)
    torch.testing.assert_close(y, z[:, -1:] + 0.25 * raw_bias)


def test_simulate_refuses_bad_shapes(siso_data):
    model = small_model("mlp", siso_data)
    tr = siso_data[0]
    with pytest.raises(ShapeError, match="y_burn_in must hold the ℓ = 3"):
        model.simulate(tr.u, tr.y[:2])
    assert model.simulate(tr.u[:3], tr.y[:3]).shape == (0, 1)  # nothing left to predict
    with pytest.raises(ShapeError, match="fewer than the window"):
        model.simulate(tr.u[:2], tr.y[:3])
    bad = tr.u.copy()
    bad[4, 0] = np.nan
    with pytest.raises(ShapeError, match="NaN"):
        model.simulate(bad, tr.y[:3])


def test_normalisation_is_training_statistics_saved_as_json(mimo_data, tmp_path):
    series = as_trajectories(mimo_data)
    norm = Normalisation.fit(series)
    y = np.concatenate([s.y for s in series])
    np.testing.assert_allclose(norm.y_mean, y.mean(axis=0))
    np.testing.assert_allclose(norm.y_std, y.std(axis=0))
    dy = np.concatenate([np.diff(s.y, axis=0) for s in series])
    np.testing.assert_allclose(norm.dy_std, dy.std(axis=0))
    small_model("mlp", mimo_data).save(tmp_path / "m")
    text = (tmp_path / "m" / "normalisation.json").read_text()
    (tmp_path / "m" / "normalisation.json").write_text(text.replace('"y_std"', '"y_sd"'))
    with pytest.raises(CheckpointError, match="missing field 'y_std'"):
        Model.load(tmp_path / "m")
