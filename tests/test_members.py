"""Members: several trainings of one recipe, their regressors averaged into one canonical
network (canonid.learning.members), and ``canonid train --members K`` choosing on validation
among the members and the means of their best (canonid.members)."""

from __future__ import annotations

import json
import math

import casadi as ca
import numpy as np
import pytest
import torch
from cli_helpers import one_line_error
from hypothesis import given, settings
from hypothesis import strategies as st
from learning_helpers import damped_split, siso_dataset_file

from canonid.cli import main
from canonid.kernel.errors import CheckpointError, ShapeError
from canonid.learning import Model, Normalisation, TrainOptions, build_net, fit
from canonid.learning.canonical import shift
from canonid.learning.members import average_members, validation_losses
from canonid.members import MEMBERS_FILE, MemberChoice, kept_candidate


def _member(seed: int, norm: Normalisation, **options) -> Model:
    """An Ours (MLP) of random weights (its affine path and cubic output drawn too)."""
    torch.manual_seed(seed)
    config = {"window": 3, "n_u": 1, "n_y": 1, "hidden": [8, 6], "activation": "silu"}
    net = build_net("mlp", **{**config, **options})
    with torch.no_grad():
        for p in net.parameters():
            p.copy_(0.3 * torch.randn_like(p))
        net.residual_scale.fill_(0.5)
    net.double().eval()  # float64, so that the averages compare at rounding level
    return Model(net, norm)


@pytest.fixture(scope="module")
def norm():
    train, _ = damped_split()
    return Normalisation.fit([type("T", (), {"u": t.u, "y": t.y})() for t in train])


OPTIONS = [
    {},
    {"linear": "skip", "residual": True},
    {"cubic": 3, "feedthrough": False},
    {"cubic": 2, "linear": "arx", "residual": True, "feedthrough": True},
]


@pytest.mark.parametrize("options", OPTIONS)
@pytest.mark.parametrize("k", [1, 2, 3])
def test_the_average_is_the_mean_of_the_members_output_maps(norm, options, k):
    members = [_member(seed, norm, **options) for seed in range(k)]
    mean = average_members(members)
    assert isinstance(mean.net, type(members[0].net))
    assert mean.net.hidden == tuple(k * h for h in members[0].net.hidden)
    z = torch.randn(64, mean.net.state_dim, dtype=torch.float64)
    u = torch.randn(64, 1, dtype=torch.float64)
    with torch.no_grad():
        want = torch.stack([m.net.one_step(z, u) for m in members]).mean(dim=0)
        got = mean.net.one_step(z, u)
    assert torch.allclose(got, want, rtol=1e-12, atol=1e-12)


def test_the_rollout_averages_at_every_step_on_its_own_predictions(norm):
    members = [_member(seed, norm, linear="skip", residual=True, cubic=2) for seed in range(3)]
    mean = average_members(members)
    nets = [m.net for m in members]
    rng = np.random.default_rng(0)
    u_past = torch.as_tensor(rng.normal(size=(5, 3, 1)))
    y_past = torch.as_tensor(rng.normal(size=(5, 3, 1)))
    u_future = torch.as_tensor(rng.normal(size=(5, 12, 1)))
    from canonid.learning.canonical import pairs_to_state

    z, want = pairs_to_state(u_past, y_past), []
    with torch.no_grad():
        for t in range(12):  # the canonical state fed with the averaged output
            y = torch.stack([n.one_step(z, u_future[:, t]) for n in nets]).mean(dim=0)
            want.append(y)
            z = shift(z, u_future[:, t], y)
        got = mean.net.rollout(u_past, y_past, u_future)
    assert torch.allclose(got, torch.stack(want, dim=1), rtol=1e-10, atol=1e-12)


def test_one_member_is_itself_and_the_average_saves_and_loads(norm, tmp_path):
    member = _member(0, norm, cubic=2, linear="skip")
    u = np.random.default_rng(1).normal(size=(3, 40, 1))
    y0 = np.random.default_rng(2).normal(size=(3, 3, 1))
    np.testing.assert_allclose(
        average_members([member]).predict(u, y0), member.predict(u, y0), rtol=1e-6, atol=1e-6
    )
    pair = [_member(s, norm, cubic=2, linear="skip") for s in (0, 1)]
    mean = average_members([Model(m.net.float(), norm) for m in pair])  # as trained and saved
    mean.save(tmp_path / "mean")
    again = Model.load(tmp_path / "mean")
    np.testing.assert_array_equal(again.predict(u, y0), mean.predict(u, y0))


@pytest.mark.parametrize("options", OPTIONS[::2])
def test_the_mean_applies_its_blocks_as_the_dense_weights_it_stores(norm, options, tmp_path):
    """Block by block (groups) is the dense network that saving, analysis and export read, in
    a simulation (no gradient) and in training (gradients flow to the blocks alone); a mean of
    means keeps every member's block."""
    members = [_member(seed, norm, **options) for seed in range(3)]
    mean = average_members(members)
    assert mean.net.groups == 3 and mean.net.config()["groups"] == 3
    dense = build_net("mlp", **{**mean.net.config(), "groups": 1}).double()
    dense.load_state_dict(mean.net.state_dict())
    z = torch.randn(16, mean.net.state_dim, dtype=torch.float64)
    u = torch.randn(16, 1, dtype=torch.float64)
    with torch.no_grad():
        want = dense.one_step(z, u)
        assert torch.allclose(mean.net.one_step(z, u), want, rtol=1e-12, atol=1e-12)
        assert torch.allclose(mean.net.one_step(z, u), want, rtol=1e-12, atol=1e-12)  # cached
    hidden = [m for m in mean.net.net if isinstance(m, torch.nn.Linear)][1]
    mean.net.one_step(z, u).sum().backward()
    dense.one_step(z, u).sum().backward()
    dense_hidden = [m for m in dense.net if isinstance(m, torch.nn.Linear)][1]
    width_in, width_out = members[0].net.hidden[:2]
    blocks = torch.block_diag(*[torch.ones(width_out, width_in, dtype=torch.float64)] * 3)
    assert torch.allclose(hidden.weight.grad, dense_hidden.weight.grad * blocks, atol=1e-12)
    mean.save(tmp_path / "mean")
    assert Model.load(tmp_path / "mean").net.groups == 3
    nested = average_members([average_members(members[:2]), average_members([members[2]] * 2)])
    assert nested.net.groups == 4
    with torch.no_grad():
        want = (members[0].net.one_step(z, u) + members[1].net.one_step(z, u)) / 4
        want = want + members[2].net.one_step(z, u) / 2
        assert torch.allclose(nested.net.one_step(z, u), want, rtol=1e-10, atol=1e-12)
    with pytest.raises(ShapeError, match="groups must be a number"):
        build_net("mlp", window=3, n_u=1, n_y=1, hidden=[8, 6], groups=4)


def test_the_mean_exports_to_casadi_with_the_numbers_it_simulates(norm):
    """Export reads the stored dense weights; CasADi's Ĥ equals the block-by-block torch one."""
    from canonid.models.learned import LearnedSystem, regressor_expr
    from canonid.models.sets import Box

    members = [_member(s, norm, cubic=2, linear="skip", residual=True) for s in range(3)]
    exported = average_members(members).export()
    net = exported.network()
    ones = np.ones(net.state_dim)
    system = LearnedSystem(
        net,
        dt=1.0,
        input_names=("u",),
        output_names=("y",),
        X=Box(-ones, ones),
        U=Box([-1.0], [1.0]),
        W=Box([0.0], [0.0]),
    )
    rng = np.random.default_rng(5)
    z, u = rng.normal(size=(32, net.state_dim)), rng.normal(size=(32, 1))
    np.testing.assert_allclose(system.h_batch(z, u), exported.H(z, u), rtol=1e-10, atol=1e-10)

    # the symbolic products skip the zeros between the blocks: about K members' instructions
    def instructions(model: Model) -> int:
        plain = model.export().network()
        z, u = ca.SX.sym("z", plain.state_dim), ca.SX.sym("u", 1)
        return ca.Function("h", [z, u], [regressor_expr(plain, z, u)]).n_instructions()

    assert instructions(average_members(members)) <= 3.2 * instructions(members[0])


def test_members_of_other_recipes_are_refused_by_name(norm):
    base = _member(0, norm)
    with pytest.raises(ShapeError, match="differs from member 1 in window"):
        average_members([base, _member(1, norm, window=4)])
    with pytest.raises(ShapeError, match="differs from member 1 in hidden"):
        average_members([base, _member(1, norm, hidden=[8, 8])])
    with pytest.raises(ShapeError, match="other statistics"):
        shifted = Normalisation.from_dict({**norm.to_dict(), "u_mean": [5.0]})
        average_members([base, Model(_member(1, norm).net, shifted)])
    with pytest.raises(ShapeError, match="Ours \\(MLP\\)"):
        average_members(
            [Model(build_net("gru", window=3, n_u=1, n_y=1, hidden_size=4, num_layers=1), norm)]
        )
    with pytest.raises(ShapeError, match="at least one"):
        average_members([])


def test_validation_losses_are_the_losses_fit_records():
    train, val = damped_split()
    options = TrainOptions(epochs=3, horizon=5, val_every=1, batch_size=8, windows_per_epoch=32)
    result = fit(train, val, model="mlp", window=3, options=options, net_options={"hidden": [8]})
    (loss,) = validation_losses([result.model], val, options)
    assert loss == pytest.approx(result.best_val_loss, rel=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    losses=st.lists(
        st.one_of(st.floats(0, 10), st.just(math.inf), st.just(math.nan)), min_size=1, max_size=4
    ),
    extra=st.lists(st.one_of(st.floats(0, 10), st.just(math.nan)), max_size=3),
)
def test_the_kept_candidate_has_the_lowest_finite_loss(losses, extra):
    seeds = list(range(7, 7 + len(losses)))
    means = list(zip(range(2, 2 + len(extra)), extra))
    kept = kept_candidate(seeds, losses, means)
    table = {f"seed {s}": loss for s, loss in zip(seeds, losses)}
    table.update({f"mean of {j}": loss for j, loss in means})
    finite = [loss for loss in table.values() if math.isfinite(loss)]
    if not finite:
        assert kept == "seed 7"
        return
    assert table[kept] == min(finite)
    first = next(name for name, loss in table.items() if loss == min(finite))
    assert kept == first  # the first on a tie: members in seed order, then the means


@given(
    losses=st.lists(st.floats(0, 10), min_size=1, max_size=4),
    extra=st.lists(st.floats(0, 10), max_size=3),
    counts=st.lists(st.integers(0, 30), min_size=7, max_size=7),
)
def test_a_candidate_answering_the_excitation_worse_than_the_runs_own_is_never_kept(
    losses, extra, counts
):
    """With the check's counts, the kept candidate has at most the run's own member's count and
    the lowest loss of those that do; the run's own member always qualifies."""
    seeds = list(range(len(losses)))
    means = list(zip(range(2, 2 + len(extra)), extra))
    outside = counts[: len(losses) + len(extra)]
    kept = kept_candidate(seeds, losses, means, outside)
    names = [f"seed {s}" for s in seeds] + [f"mean of {j}" for j, _ in means]
    table = dict(zip(names, [*losses, *extra]))
    allowed = [n for n, c in zip(names, outside) if c <= outside[0]]
    assert kept in allowed
    assert table[kept] == min(table[n] for n in allowed)


# ----------------------------------------------------------------- the command, as typed
@pytest.fixture(scope="module")
def dataset_path(tmp_path_factory):
    return siso_dataset_file(tmp_path_factory.mktemp("data"))


def _train(dataset_path, run, *extra):
    return main(
        [
            "train",
            str(dataset_path),
            "--window",
            "3",
            "--epochs",
            "2",
            "--hidden",
            "16,16",
            "--out",
            str(run),
            "--no-progress",
            "--device",
            "cpu",
            "--threads",
            "1",
            *extra,
        ]
    )


def test_train_with_members_keeps_the_lowest_validation_loss(dataset_path, tmp_path, capsys):
    run = tmp_path / "run"
    assert _train(dataset_path, run, "--members", "3") == 0
    out = capsys.readouterr().out
    body = json.loads((run / MEMBERS_FILE).read_text())
    choice = MemberChoice.read(run)
    assert body["count"] == 3 and choice.seeds == (0, 1, 2)
    assert [m["seed"] for m in body["members"]] == [0, 1, 2]
    assert [j for j, _ in choice.means] == [2, 3]
    assert choice.kept_loss == min(choice.losses + tuple(loss for _, loss in choice.means))
    assert f"kept: {choice.kept}" in out
    for seed in (1, 2):  # each further member is a run folder of its own, of the same network
        member = Model.load(run / "members" / f"s{seed}")
        assert member.info["training"]["options"]["seed"] == seed
        assert json.loads((run / "members" / f"s{seed}" / "run.json").read_text())["window"] == 3
    kept = Model.load(run)
    if choice.kept != "seed 0":  # the run's own member moved aside, the choice in its place
        assert kept.info["members"]["kept"] == choice.kept
        assert (run / "members" / "s0" / "weights.pt").is_file()
    # the kept model's validation loss, by the same routine, is the one recorded
    from canonid.runfolder import RunRecipe, load_splits

    recipe = RunRecipe.read(run)
    _, _, val, _, _ = load_splits(recipe)
    (loss,) = validation_losses([kept], val, recipe.options())
    assert loss == pytest.approx(choice.kept_loss, rel=1e-6)
    metrics = json.loads((run / "metrics.json").read_text())
    assert math.isfinite(metrics["rmse"])
    assert main(["evaluate", str(run), "--eval-horizon", "20", "--stride", "5"]) == 0

    # resumed, the finished run and its members choose the same again, to the byte; the plan
    # written before the first member trained is what tells --resume how many members there are
    before = {name: (run / name).read_bytes() for name in (MEMBERS_FILE, "weights.pt")}
    plan = {"format": "canonid-members", "count": 3, "members": [], "means": [], "kept": None}
    (run / MEMBERS_FILE).write_text(json.dumps(plan))
    with pytest.raises(CheckpointError, match="have not all trained yet"):
        MemberChoice.read(run)
    assert main(["train", "--resume", "--out", str(run), "--no-progress", "--threads", "1"]) == 0
    assert {name: (run / name).read_bytes() for name in before} == before


def test_members_side_by_side_train_as_they_would_alone_on_one_thread(
    dataset_path, tmp_path, capsys
):
    """With two threads the members train in worker processes of one thread each: the same
    weights and scores as ``--threads 1``, one after the other; each says when it is done."""
    alone, side = tmp_path / "alone", tmp_path / "side"
    assert _train(dataset_path, alone, "--members", "3") == 0
    shown = ["--window", "3", "--epochs", "2", "--hidden", "16,16", "--device", "cpu"]
    args = ["train", str(dataset_path), *shown, "--out", str(side), "--members", "3"]
    assert main([*args, "--threads", "2"]) == 0  # with progress, this time
    err = capsys.readouterr().err
    assert "members: training seeds 1, 2 side by side" in err
    assert all(f"members: seed {s} trained in {side / 'members' / f's{s}'}" in err for s in (1, 2))
    for seed in (1, 2):
        one, two = (Model.load(run / "members" / f"s{seed}") for run in (alone, side))
        state = two.net.state_dict()
        assert all(torch.equal(v, state[k]) for k, v in one.net.state_dict().items())
        metrics = [
            json.loads((run / "members" / f"s{seed}" / "metrics.json").read_text())
            for run in (alone, side)
        ]
        assert metrics[0]["rollout_mse"] == metrics[1]["rollout_mse"]
    losses = [json.loads((run / MEMBERS_FILE).read_text())["members"] for run in (alone, side)]
    assert [m["val_loss"] for m in losses[0][1:]] == [m["val_loss"] for m in losses[1][1:]]
    # stopped while the members trained (the plan pending, a member's model not yet written
    # beside its checkpoint), --resume continues in the workers and gives the same bytes
    before = {name: (side / name).read_bytes() for name in (MEMBERS_FILE, "weights.pt")}
    plan = {"format": "canonid-members", "count": 3, "members": [], "means": [], "kept": None}
    (side / MEMBERS_FILE).write_text(json.dumps(plan))
    for name in ("weights.pt", "config.json", "metrics.json"):
        (side / "members" / "s2" / name).unlink()
    resume = ["train", "--resume", "--out", str(side), "--no-progress", "--threads", "2"]
    assert main(resume) == 0
    assert {name: (side / name).read_bytes() for name in before} == before


def test_the_mean_becomes_the_run_model_when_it_validates_best(dataset_path, tmp_path, monkeypatch):
    from canonid import members as members_module

    monkeypatch.setattr(members_module, "kept_candidate", lambda *candidates: "mean of 2")
    run = tmp_path / "run"
    assert _train(dataset_path, run, "--members", "2") == 0
    kept = Model.load(run)
    first, second = Model.load(run / "members" / "s0"), Model.load(run / "members" / "s1")
    assert kept.info["members"] == {"kept": "mean of 2", "seeds": [0, 1], "file": MEMBERS_FILE}
    assert kept.net.hidden == (32, 32)
    u = np.random.default_rng(3).normal(size=(2, 30, 1))
    y0 = np.random.default_rng(4).normal(size=(2, 3, 1))
    np.testing.assert_allclose(
        kept.predict(u, y0), average_members([first, second]).predict(u, y0), atol=1e-6
    )
    assert json.loads((run / MEMBERS_FILE).read_text())["members"][0]["folder"] == "members/s0"
    # chosen again on --resume, the run's own member: its model is the run folder's again
    own = (run / "members" / "s0" / "weights.pt").read_bytes()
    monkeypatch.setattr(members_module, "kept_candidate", lambda *candidates: "seed 0")
    assert main(["train", "--resume", "--out", str(run), "--no-progress", "--threads", "1"]) == 0
    assert (run / "weights.pt").read_bytes() == own and not (run / "members" / "s0").exists()
    assert "members" not in Model.load(run).info
    assert json.loads((run / MEMBERS_FILE).read_text())["members"][0]["folder"] == "."


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (("--members", "0"), "--members must be an integer >= 1"),
        (("--members", "2", "--model", "gru"), "averages Ours (MLP) networks"),
        (("--members", "2", "--window", "3,4"), "does not combine with a list of windows"),
    ],
)
def test_members_where_they_do_not_apply_are_refused(dataset_path, tmp_path, capsys, extra, needle):
    argv = ["train", str(dataset_path), "--out", str(tmp_path / "run"), "--no-progress"]
    if "--window" not in extra:
        argv += ["--window", "3"]
    one_line_error(capsys, main([*argv, *extra]), needle)
    assert not (tmp_path / "run").exists()


def test_resume_with_members_adds_them_to_a_finished_run(dataset_path, tmp_path):
    run = tmp_path / "run"
    assert _train(dataset_path, run) == 0
    assert not (run / MEMBERS_FILE).exists()  # one member: no members file, as before
    resume = ["train", "--resume", "--out", str(run), "--no-progress", "--threads", "1"]
    assert main([*resume, "--members", "2"]) == 0
    choice = MemberChoice.read(run)
    assert choice.seeds == (0, 1) and (run / "members" / "s1" / "weights.pt").is_file()
