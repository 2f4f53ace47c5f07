"""The search that chooses canonid's default model (:mod:`canonid.learning.search`): successive
halving keeps the best candidate when the ranks are known, never keeps a diverging one, its rungs
are prefixes of one run (same bytes), and ``canonid train`` reports validation only."""

from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import CheckpointError, OptionError
from canonid.learning.search import (
    Candidate,
    Search,
    SearchRow,
    candidate_table,
    fitting_windows,
    rung_budgets,
    successive_halving,
)


def test_rung_budgets_follow_the_halving_rate():
    assert rung_budgets(8, 600, 3) == [(8, 67), (2, 200), (1, 600)]
    assert rung_budgets(2, 600, 3) == [(2, 200), (1, 600)]
    assert rung_budgets(1, 600, 3) == [(1, 600)]
    assert rung_budgets(27, 81, 3) == [(27, 3), (9, 9), (3, 27), (1, 81)]
    for n in range(1, 40):
        rungs = rung_budgets(n, 600, 3)
        counts = [c for c, _ in rungs]
        assert counts[0] == n and counts[-1] == 1 and rungs[-1][1] == 600
        assert all(b == max(1, a // 3) for a, b in itertools.pairwise(counts))
    with pytest.raises(OptionError):
        rung_budgets(0, 600, 3)


def _synthetic(losses: dict[Candidate, float], calls: list[tuple[Candidate, int, int]]):
    """A trainer whose candidate ``c`` reaches ``losses[c] · (1 + 1/until)``: the ranks are the
    same at every budget, so the best candidate is known."""

    def train(candidate: Candidate, rung: int, until: int) -> SearchRow:
        calls.append((candidate, rung, until))
        base = losses[candidate]
        loss = base * (1 + 1 / until) if math.isfinite(base) else math.inf
        return SearchRow(candidate, rung, until, loss, until, until, "paused")

    return train


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.01, 100.0), min_size=1, max_size=12, unique=True))
def test_successive_halving_keeps_the_best_when_ranks_are_known(values):
    table = tuple(Candidate(window=i + 1) for i in range(len(values)))
    losses = dict(zip(table, values, strict=True))
    calls: list[tuple[Candidate, int, int]] = []
    done = successive_halving(Search(table, epochs=90), _synthetic(losses, calls))
    assert done.chosen == min(table, key=losses.__getitem__)
    # each rung trained exactly its entrants, at its budget
    for rung, (count, until) in enumerate(done.budgets):
        trained = [c for c, r, u in calls if r == rung]
        assert len(trained) == count and all(u == until for _, r, u in calls if r == rung)


def test_a_diverging_candidate_is_never_kept():
    table = candidate_table((10, 20, 40), (0, 16))
    losses = {c: math.inf for c in table}
    worst = table[-1]
    losses[worst] = 50.0  # the only finite one, however bad
    done = successive_halving(Search(table, epochs=27), _synthetic(losses, []))
    assert done.chosen == worst
    assert all(r.finite for r in done.rows if r.rung > 0)
    with pytest.raises(OptionError, match=r"every one diverged"):
        successive_halving(Search(table, epochs=27), _synthetic({c: math.inf for c in table}, []))


def test_the_search_record_round_trips_and_shows_validation_only():
    table = candidate_table((10, 20), (0, 16))
    losses = {c: float(i + 1) for i, c in enumerate(table)}
    done = successive_halving(Search(table, epochs=30, val_n_init=20), _synthetic(losses, []))
    again = Search.from_dict(json.loads(json.dumps(done.to_dict())), where="search.json")
    assert again == done and again.chosen == table[0]
    text = done.table() + done.summary()
    assert "test" not in text.lower() and "l10 *" in text
    with pytest.raises(CheckpointError, match=r"search\.json"):
        Search.from_dict({"format": "canonid-search", "rows": []}, where="search.json")


def test_a_resumed_search_trains_only_what_is_missing():
    table = candidate_table((10, 20, 40), (0,))
    losses = {c: float(i + 1) for i, c in enumerate(table)}
    first: list[tuple[Candidate, int, int]] = []
    plan = Search(table, epochs=9)
    partial = plan.with_row(_synthetic(losses, first)(table[0], 0, 3))
    calls: list[tuple[Candidate, int, int]] = []
    done = successive_halving(partial, _synthetic(losses, calls))
    assert (table[0], 0, 3) not in calls and done.chosen == table[0]


def test_fitting_windows_need_twice_the_window_in_validation():
    def rec(n: int) -> Trajectory:
        return Trajectory(u=np.zeros((n, 1)), y=np.zeros((n, 1)))

    assert fitting_windows([rec(500)], [rec(100)], (10, 20, 40, 80), 50) == [10, 20, 40]
    assert fitting_windows([rec(60)], [rec(500)], (10, 20), 50) == [10]


def _system(seed: int, records: int, length: int) -> list[Trajectory]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(records):
        u = rng.standard_normal((length, 1))
        y = np.zeros((length, 1))
        for t in range(1, length):
            y[t] = 0.8 * y[t - 1] + 0.3 * np.tanh(u[t - 1])
        out.append(Trajectory(u=u, y=y))
    return out


def test_rungs_are_prefixes_of_one_run(tmp_path):
    """A run paused at a rung's budget and continued ends with the bytes of the run trained in
    one go: the search's chosen model is the model trained alone."""
    from canonid.learning.training import TrainOptions, fit

    train, val = _system(0, 2, 200), _system(1, 1, 120)
    opts = TrainOptions(
        epochs=6,
        batch_size=8,
        lr=3e-3,
        horizon=5,
        windows_per_epoch=32,
        checkpoint_every=2,
        val_measure="simulation",
        val_n_init=8,
        device="cpu",
    )
    common = dict(model="mlp", window=4, options=opts, net_options={"hidden": [8, 8], "cubic": 2})
    fit(train, val, **common, run_dir=tmp_path / "paused", until=2)
    resumed = fit(train, val, **common, run_dir=tmp_path / "paused", resume=True)
    alone = fit(train, val, **common, run_dir=tmp_path / "alone")
    assert resumed.best_val_loss == alone.best_val_loss
    assert (tmp_path / "paused/weights.pt").read_bytes() == (
        tmp_path / "alone/weights.pt"
    ).read_bytes()


def test_simulation_loss_is_the_field_s_simulation_score(tmp_path):
    """The validation measure equals the simulation MSE of :func:`canonid.learning.evaluate`
    (normalised units, same samples), so the search ranks by what the benchmarks report."""
    import torch

    from canonid.learning.data import WindowBank
    from canonid.learning.evaluate import simulate_records
    from canonid.learning.training import TrainOptions, fit, simulation_loss

    train, val = _system(2, 2, 200), _system(3, 2, 150)
    opts = TrainOptions(epochs=2, batch_size=8, horizon=5, windows_per_epoch=16, device="cpu")
    model = fit(
        train, val, model="mlp", window=4, options=opts, net_options={"hidden": [8], "cubic": 0}
    ).model
    norm = model.norm
    bank = WindowBank(val, norm, dtype=torch.float64)
    ours = simulation_loss(model.net.double(), bank, 10)
    model.net.float()
    sims = simulate_records(model, val, 10)
    errors = np.concatenate(
        [((sim[-140:] - tr.y[10:]) / norm.y_std) ** 2 for sim, tr in zip(sims, val, strict=True)]
    )
    assert ours == pytest.approx(float(errors.mean()), rel=1e-4)


def test_train_reports_validation_only_and_resumes_a_killed_search(tmp_path, capsys):
    """``canonid train`` without --cubic searches; its output and files hold no test score; a
    search killed mid-rung and resumed gives the bytes of an uninterrupted one."""
    from canonid.cli import main
    from canonid.kernel.dataset import Dataset
    from tests.test_kill_resume import KILLED_RUN

    parts = {"train": _system(4, 3, 300), "val": _system(5, 1, 200), "test": _system(6, 1, 200)}
    data = Dataset(splits=parts, dt=1.0, input_names=("u",), output_names=("y",))
    path = data.save(tmp_path / "data.npz")
    argv = [
        "train",
        str(path),
        "--window",
        "4",
        "--profile",
        "tiny",
        "--epochs",
        "6",
        "--hidden",
        "8,8",
        "--threads",
        "1",
        "--no-progress",
    ]
    assert main([*argv, "--out", str(tmp_path / "whole")]) == 0
    printed = capsys.readouterr()
    assert "[val]" in printed.out and "[test]" not in printed.out + printed.err
    assert "l4-c16" in printed.out and "l4 " in printed.out  # the candidate table
    whole = tmp_path / "whole"
    metrics = json.loads((whole / "metrics.json").read_text())
    assert metrics["data"]["split"] == "val"
    texts = [p.read_text(errors="ignore") for p in whole.rglob("*.json")]
    assert not any('"split": "test"' in t for t in texts)
    assert not (whole / "test-ledger.jsonl").exists()  # train read no test split
    search = Search.read(whole)
    assert search.chosen is not None and len(search.candidates) == 2

    killed = tmp_path / "killed"
    done = subprocess.run(
        [sys.executable, "-c", KILLED_RUN, "4", "1", *argv, "--out", str(killed)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == -9, done.stderr
    assert main(["train", "--resume", "--out", str(killed), "--threads", "1", "--no-progress"]) == 0
    for name in ("weights.pt", "config.json", "metrics.json"):
        assert (killed / name).read_bytes() == (whole / name).read_bytes(), name

    def losses(folder):  # the search's record but for the CPU seconds it spent
        rows = Search.read(folder).to_dict()["rows"]
        return [{k: v for k, v in row.items() if k != "cpu_seconds"} for row in rows]

    assert losses(killed) == losses(whole)


def test_the_cubic_axis_is_open_only_for_auto():
    from canonid.learning.search import CUBIC_UNITS, cubic_axis

    assert cubic_axis("auto") == CUBIC_UNITS
    assert cubic_axis(0) == (0,) and cubic_axis(8) == (8,)
    assert cubic_axis(None) == (0,) and cubic_axis(True) == (0,)  # no branch; a flag is no count
