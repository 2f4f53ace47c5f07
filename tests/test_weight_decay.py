"""Weight decay: ``"auto"`` means a small decay on short records only, and CPU training with
weight decay flushes subnormals without leaving the process flushing."""

from __future__ import annotations

import dataclasses
import json
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from learning_helpers import damped_split

from canonid.kernel.catalog import SMALL_RECORD_SAMPLES, SMALL_RECORD_WEIGHT_DECAY
from canonid.learning import TrainOptions, fit
from canonid.learning.batched import Candidate, fit_batched
from canonid.learning.training import OptionError, flushed_subnormals, resolve_weight_decay
from canonid.profiles import train_options

TINY = {"hidden": [16, 16], "feedthrough": True, "residual": False, "linear": "off"}
#: the smallest positive normal float32 and a product of it that is subnormal
TINY_NORMAL = float(np.finfo(np.float32).tiny)


def subnormal_product() -> float:
    """``tiny × 1e-3`` in float32 on the CPU: subnormal, or 0 when subnormals are flushed."""
    return float(torch.tensor([TINY_NORMAL]) * torch.tensor([1e-3]))


@pytest.fixture(scope="module")
def data():
    return damped_split()


def options(**kw) -> TrainOptions:
    base = {"epochs": 3, "batch_size": 8, "lr": 1e-3, "horizon": 8, "windows_per_epoch": 16}
    return TrainOptions(**{**base, "seed": 3, "device": "cpu", **kw})


@settings(max_examples=40, deadline=None)
@given(lengths=st.lists(st.integers(10, 4_000), min_size=1, max_size=6))
def test_auto_decays_weights_on_records_under_the_threshold_only(lengths):
    records = [SimpleNamespace(T=T) for T in lengths]
    resolved = resolve_weight_decay(TrainOptions(weight_decay="auto"), records)
    small = sum(lengths) < SMALL_RECORD_SAMPLES
    assert resolved.weight_decay == (SMALL_RECORD_WEIGHT_DECAY if small else 0.0)
    # a number is kept as given
    assert resolve_weight_decay(TrainOptions(weight_decay=3e-4), records).weight_decay == 3e-4


def test_the_default_profile_decays_weights_by_auto_and_bad_values_are_named():
    assert train_options("quick").weight_decay == "auto"
    assert train_options("paper").weight_decay == 0.0
    for bad in (-1e-5, "sometimes", float("nan")):
        with pytest.raises(OptionError, match="weight_decay must be >= 0 or 'auto'"):
            TrainOptions(weight_decay=bad)


def test_auto_trains_exactly_as_the_value_it_resolves_to_and_records_that_value(data):
    train, val = data  # 240 samples: a short record
    auto = fit(
        train, val, model="mlp", window=3, options=options(weight_decay="auto"), net_options=TINY
    )
    given_value = fit(
        train,
        val,
        model="mlp",
        window=3,
        options=options(weight_decay=SMALL_RECORD_WEIGHT_DECAY),
        net_options=TINY,
    )
    recorded = auto.model.info["training"]["options"]["weight_decay"]
    assert recorded == SMALL_RECORD_WEIGHT_DECAY
    for key, value in auto.model.net.state_dict().items():
        assert torch.equal(value, given_value.model.net.state_dict()[key]), key
    assert auto.best_val_loss == given_value.best_val_loss


def test_weight_decay_changes_the_weights(data):
    train, val = data
    plain = fit(train, val, model="mlp", window=3, options=options(), net_options=TINY)
    decayed = fit(
        train, val, model="mlp", window=3, options=options(weight_decay=1e-2), net_options=TINY
    )
    assert any(
        not torch.equal(v, decayed.model.net.state_dict()[k])
        for k, v in plain.model.net.state_dict().items()
    )


def test_subnormals_are_flushed_on_the_cpu_while_weight_decay_trains_and_only_then():
    assert subnormal_product() > 0  # torch's default: subnormals kept
    with flushed_subnormals(torch.device("cpu"), 1e-5):
        assert subnormal_product() == 0.0
    assert subnormal_product() > 0
    with flushed_subnormals(torch.device("cpu"), 0.0):
        assert subnormal_product() > 0  # no weight decay: the arithmetic is left as it is
    with flushed_subnormals(torch.device("cpu"), 0.0, always=True):
        assert subnormal_product() == 0.0  # a reduction's training asks for it regardless
    assert subnormal_product() > 0
    with pytest.raises(RuntimeError), flushed_subnormals(torch.device("cpu"), 1e-5):
        raise RuntimeError("an interrupted run")
    assert subnormal_product() > 0


def test_training_with_weight_decay_flushes_during_the_run_and_restores_after(data, monkeypatch):
    train, val = data
    seen = []
    fit(
        train,
        val,
        model="mlp",
        window=3,
        options=options(weight_decay=1e-4),
        net_options=TINY,
        callback=lambda report: seen.append(subnormal_product()),
    )
    assert seen and all(v == 0.0 for v in seen)
    assert subnormal_product() > 0
    seen.clear()
    fit(
        train,
        val,
        model="mlp",
        window=3,
        options=options(),
        net_options=TINY,
        callback=lambda report: seen.append(subnormal_product()),
    )
    assert seen and all(v > 0 for v in seen)


def test_stacked_candidates_resolve_auto_as_fit_does(data):
    train, val = data
    base = options(weight_decay="auto")
    result = fit_batched(
        train,
        val,
        [Candidate.of(seed=3), Candidate.of(seed=3, weight_decay=0.0)],
        window=3,
        options=base,
        net_options=TINY,
        ensemble=0,
    )
    auto, zero = result.runs
    assert auto.model.info["training"]["options"]["weight_decay"] == SMALL_RECORD_WEIGHT_DECAY
    assert zero.model.info["training"]["options"]["weight_decay"] == 0.0
    alone = fit(
        train,
        val,
        model="mlp",
        window=3,
        options=dataclasses.replace(base, weight_decay=SMALL_RECORD_WEIGHT_DECAY),
        net_options=TINY,
    )
    assert auto.best_val_loss == pytest.approx(alone.best_val_loss, rel=1e-4)


def test_the_command_line_takes_a_weight_decay_or_auto_and_records_the_value_used(
    data, tmp_path, capsys
):
    from cli_helpers import one_line_error

    from canonid.cli import main
    from canonid.kernel.dataset import Dataset, Trajectory

    train, val = data
    records = {
        part: tuple(Trajectory(u=t.u, y=t.y) for t in found)
        for part, found in (("train", train), ("val", val), ("test", val))
    }
    found = Dataset(splits=records, dt=1.0, input_names=("u",), output_names=("y",))
    path = found.save(tmp_path / "d" / "dataset.npz")
    fast = ["--window", "3", "--profile", "tiny", "--no-progress", "--device", "cpu"]
    for text, used in (("auto", SMALL_RECORD_WEIGHT_DECAY), ("0", 0.0), ("2e-4", 2e-4)):
        run = tmp_path / f"run-{text}"
        assert main(["train", str(path), "--weight-decay", text, "--out", str(run), *fast]) == 0
        config = json.loads((run / "config.json").read_text())
        assert config["info"]["training"]["options"]["weight_decay"] == used
    code = main(["train", str(path), "--weight-decay", "abc", "--out", str(tmp_path / "r"), *fast])
    one_line_error(capsys, code, "--weight-decay: expected a number >= 0 or auto, got 'abc'")
    assert not (tmp_path / "r").exists()


def test_subnormals_other_threads_computed_are_zeroed_after_every_step(data, monkeypatch):
    """The CPU's flush flag is per thread: entries another torch thread left subnormal are
    zeroed after each optimiser step, in weights and Adam's moments; nothing else changes."""
    import canonid.learning.training as training
    from canonid.learning.training import flush_subnormal_tensors

    values = torch.tensor([TINY_NORMAL * 1e-3, -TINY_NORMAL * 1e-2, TINY_NORMAL, 0.5, -2.0])
    flush_subnormal_tensors([values, torch.tensor([3]), "not a tensor"])
    assert values.tolist() == [0.0, 0.0, TINY_NORMAL, 0.5, -2.0]
    calls = []
    original = training.flush_subnormal_tensors

    def counted(tensors):
        tensors = list(tensors)
        calls.append(len(tensors))
        original(tensors)

    monkeypatch.setattr(training, "flush_subnormal_tensors", counted)
    train, val = data
    fit(train, val, model="mlp", window=3, options=options(weight_decay=1e-4), net_options=TINY)
    n_params = 6  # three layers' weights and biases
    assert calls and all(n >= 3 * n_params for n in calls)  # weights, both moments (and step)
    calls.clear()
    fit(train, val, model="mlp", window=3, options=options(), net_options=TINY)
    assert calls == []
