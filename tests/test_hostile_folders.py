"""A folder received from someone else is data, never a weapon (issue 29).

Each test builds its hostile folder itself: symlinks planted where canonid writes, planted
temporary names, a compiled-solver cache that others can write (with a valid checksum), a
``config.json`` whose architecture the weights do not hold. Each asserts that no victim file
changed, nothing planted ran or was loaded, and a refusal is one line naming the file and field.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
import torch
from learning_helpers import damped_siso, trajectories
from matplotlib.figure import Figure

from canonid.kernel.errors import OutputError
from canonid.kernel.io import atomic_copy, atomic_write_figure
from canonid.learning import Model, Normalisation, as_series, build_net
from canonid.learning.plots import plot_rollouts, plot_training_curve

VICTIM_TEXT = "the victim's own bytes\n"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _plant_symlink(link: Path, outside: Path) -> Path:
    """``link`` made a symlink to a victim file in ``outside``; returns the victim."""
    outside.mkdir(exist_ok=True)
    victim = outside / f"victim-of-{link.name}"
    victim.write_text(VICTIM_TEXT, encoding="utf-8")
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(victim)
    return victim


def _assert_replaced_not_followed(path: Path, victim: Path, magic: bytes) -> None:
    assert victim.read_text(encoding="utf-8") == VICTIM_TEXT
    assert not path.is_symlink() and path.is_file()
    assert path.read_bytes().startswith(magic)
    assert not [p for p in path.parent.iterdir() if p.name.endswith(".tmp")]


@pytest.fixture(scope="module")
def siso_data():
    return trajectories(damped_siso(), 2, 30, noise=0.01, seed=1)


def _small_mlp(data, *, window: int = 3, hidden=(16, 16)) -> Model:
    torch.manual_seed(0)
    series = as_series(data)
    net = build_net("mlp", window=window, n_u=1, n_y=1, hidden=list(hidden))
    return Model(net, Normalisation.fit(series))


# ---------------------------------------------------------------------- figures
def test_a_figure_replaces_a_planted_symlink_not_its_target(tmp_path):
    fig = Figure(figsize=(2, 2))
    fig.subplots().plot([0, 1], [1, 0])
    for name, magic in (("a.png", PNG_MAGIC), ("b.pdf", b"%PDF"), ("c.svg", b"<?xml")):
        victim = _plant_symlink(tmp_path / "run" / name, tmp_path / "outside")
        assert atomic_write_figure(tmp_path / "run" / name, fig) == tmp_path / "run" / name
        _assert_replaced_not_followed(tmp_path / "run" / name, victim, magic)


def test_the_same_figure_gives_the_same_bytes(tmp_path):
    fig = Figure(figsize=(2, 2))
    fig.subplots().plot([0, 1], [1, 0])
    first = atomic_write_figure(tmp_path / "a.png", fig, metadata={"Software": None}).read_bytes()
    again = atomic_write_figure(tmp_path / "b.png", fig, metadata={"Software": None}).read_bytes()
    assert first == again


def test_a_figure_that_cannot_be_written_is_one_output_error(tmp_path):
    fig = Figure(figsize=(2, 2))
    (tmp_path / "taken").mkdir()
    with pytest.raises(OutputError, match=r"cannot write .*taken"):
        atomic_write_figure(tmp_path / "taken", fig, format="png")
    assert [p.name for p in tmp_path.iterdir()] == ["taken"]


def test_training_figures_replace_planted_symlinks(siso_data, tmp_path):
    run = tmp_path / "run"
    history = [
        {"epoch": e, "train_loss": 1.0 / (e + 1), "val_loss": 2.0 / (e + 1), "horizon": 5}
        for e in range(4)
    ]
    curve = _plant_symlink(run / "training_curve.png", tmp_path / "outside")
    rollouts = _plant_symlink(run / "rollouts.png", tmp_path / "outside")
    plot_training_curve(history, run / "training_curve.png")
    plot_rollouts(_small_mlp(siso_data), siso_data, run / "rollouts.png", n_init=3, count=1)
    _assert_replaced_not_followed(run / "training_curve.png", curve, PNG_MAGIC)
    _assert_replaced_not_followed(run / "rollouts.png", rollouts, PNG_MAGIC)


def test_the_analysis_figure_replaces_a_planted_symlink(tmp_path):
    from canonid.analysis.estimate import Budget
    from canonid.analysis.report import analyze
    from canonid.models.registry import get_system

    report = analyze(
        get_system("linear"), [2], trials=4, budget=Budget(boxes=50, samples=32, starts=1), starts=1
    )
    victim = _plant_symlink(tmp_path / "bound.png", tmp_path / "outside")
    report.figure(tmp_path / "bound.png")
    _assert_replaced_not_followed(tmp_path / "bound.png", victim, PNG_MAGIC)


# ---------------------------------------------------------------------- atomic copy
def test_atomic_copy_replaces_a_planted_symlink_and_ignores_planted_temporary_names(tmp_path):
    source = tmp_path / "candidate" / "weights.pt"
    source.parent.mkdir()
    source.write_bytes(b"chosen weights" * 1000)
    run = tmp_path / "run"
    victims = [
        _plant_symlink(run / name, tmp_path / "outside")
        for name in ("weights.pt", ".weights.pt.tmp", ".weights.pt.tmp.tmp")
    ]
    assert atomic_copy(source, run / "weights.pt") == run / "weights.pt"
    assert (run / "weights.pt").read_bytes() == source.read_bytes()
    assert not (run / "weights.pt").is_symlink()
    assert all(v.read_text(encoding="utf-8") == VICTIM_TEXT for v in victims)
    leftovers = sorted(p.name for p in run.iterdir())
    assert leftovers == [".weights.pt.tmp", ".weights.pt.tmp.tmp", "weights.pt"]  # planted ones
    assert stat.S_IMODE((run / "weights.pt").stat().st_mode) == 0o666 & ~_umask()


def test_a_failed_atomic_copy_leaves_the_old_file_and_no_temporary_file(tmp_path):
    (tmp_path / "weights.pt").write_bytes(b"old")
    with pytest.raises(OutputError, match=r"cannot copy .*missing\.pt to .*weights\.pt"):
        atomic_copy(tmp_path / "missing.pt", tmp_path / "weights.pt")
    assert [p.name for p in tmp_path.iterdir()] == ["weights.pt"]
    assert (tmp_path / "weights.pt").read_bytes() == b"old"


@pytest.mark.xfail(
    strict=True,
    raises=AssertionError,
    reason="canonid/selection.py adopts through a fixed '.NAME.tmp' until it calls atomic_copy",
)
def test_window_auto_adopts_the_chosen_model_without_a_fixed_temporary_name(tmp_path):
    from canonid.selection import ADOPTED, _adopt

    chosen = tmp_path / "candidates" / "w3"
    chosen.mkdir(parents=True)
    for name in ADOPTED:
        (chosen / name).write_text(f"chosen {name}\n", encoding="utf-8")
    run = tmp_path / "run"
    victims = [_plant_symlink(run / f".{name}.tmp", tmp_path / "outside") for name in ADOPTED]
    _adopt(chosen, run)
    assert all(v.read_text(encoding="utf-8") == VICTIM_TEXT for v in victims)
    for name in ADOPTED:
        assert not (run / name).is_symlink()
        assert (run / name).read_text(encoding="utf-8") == f"chosen {name}\n"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
