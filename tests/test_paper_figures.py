"""Figures a researcher can put in a paper: units on the axes, the model's table name, records
named by experiment, legends off the data, the kept epoch marked, vector formats; and the
reproduce report as real HTML."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import torch
from cli_helpers import evaluated
from learning_helpers import damped_siso, siso_dataset_file, trajectories
from matplotlib.backends.backend_agg import FigureCanvasAgg

from canonid.cli import main
from canonid.kernel.catalog import MODEL_LABELS, model_label
from canonid.kernel.dataset import Trajectory
from canonid.learning import Model, Normalisation, build_net
from canonid.learning.plots import record_title, rollouts_figure, training_curve_figure
from canonid.models.registry import signal_units
from canonid.report import Report, inline_html

MAGIC = {"png": b"\x89PNG\r\n\x1a\n", "pdf": b"%PDF", "svg": b"<?xml"}


def _drawn(fig):
    FigureCanvasAgg(fig).draw()
    return fig


def _legend_off_the_axes(fig) -> None:
    (legend,) = fig.legends
    box = legend.get_window_extent()
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent()), ax.get_ylabel()


@pytest.fixture(scope="module")
def named_records():
    data = trajectories(damped_siso(), 2, 40, noise=0.01, seed=1)
    names = ("run = a", "run = b")
    return [Trajectory(u=t.u, y=t.y, info={"experiment": n}) for t, n in zip(data, names)]


def _mlp(records) -> Model:
    torch.manual_seed(0)
    net = build_net("mlp", window=3, n_u=1, n_y=1, hidden=[8])
    return Model(net, Normalisation.fit(records))


def test_rollouts_name_the_model_the_records_and_the_units(named_records):
    fig = _drawn(
        rollouts_figure(
            _mlp(named_records),
            named_records,
            n_init=5,
            output_names=["level"],
            output_units=["m"],
            dt=0.5,
            source="test.csv [all]",
        )
    )
    width, height = fig.get_size_inches()
    assert width >= 7 and height >= 4.5
    axes = fig.axes
    assert axes[0].get_ylabel() == "level [m]" and axes[0].get_xlabel() == "time [s]"
    assert [ax.get_title() for ax in axes] == ["run = a", "run = b"]
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "Ours (MLP), open loop" in labels and not any("mlp" in t for t in labels)
    assert "test.csv [all]" in fig.get_suptitle()
    _legend_off_the_axes(fig)


def test_a_record_without_a_name_is_named_by_what_its_loader_recorded():
    u, y = np.zeros((4, 1)), np.zeros((4, 1))
    assert record_title(Trajectory(u=u, y=y), 2) == "record 2"
    generated = Trajectory(u=u, y=y, info={"split": "test", "index": 1})
    assert record_title(generated, 0) == "test experiment 1"
    part = Trajectory(u=u, y=y, info={"experiment": "a.csv", "samples": [80, 100]})
    assert record_title(part, 0) == "a.csv (samples 80–99)"
    assert record_title(Trajectory(u=u, y=y, info={"flight": "x", "chunk": 2}), 0) == (
        "flight x, chunk 2"
    )


def test_csv_records_carry_their_experiment(tmp_path):
    from canonid.datagen.loaders import load_csv

    rows = ["exp,u,y"] + [f"{e},{i},{i * 2}" for e in ("left", "right") for i in range(5)]
    (tmp_path / "d.csv").write_text("\n".join(rows) + "\n")
    with_column = load_csv(
        tmp_path / "d.csv", inputs=["u"], outputs=["y"], dt=0.1, experiment_column="exp"
    )
    names = [record_title(tr, i) for i, tr in enumerate(with_column.split("train"))]
    assert names == ["exp = left", "exp = right"]
    whole = load_csv(tmp_path / "d.csv", inputs=["u"], outputs=["y"], dt=0.1)
    assert record_title(whole.split("train")[0], 0) == "d.csv"


def test_the_training_curve_separates_the_losses_and_marks_the_kept_epoch():
    val = [1.0, 0.5, 0.2, 0.3, 0.25]  # least at epoch 2: the kept weights
    history = [
        {"epoch": e, "train_loss": 0.1 / (e + 1) if e else None, "val_loss": v, "horizon": e + 1}
        for e, v in enumerate(val)
    ]
    fig = _drawn(training_curve_figure(history))
    labels = {ax.get_ylabel() for ax in fig.axes}
    assert any(label.startswith("training loss") for label in labels)
    assert any(label.startswith("validation rollout MSE") for label in labels)
    assert "H [samples]" in labels  # the rollout length on its own axis
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "kept weights (epoch 2)" in texts
    loss_axes = [ax for ax in fig.axes if "loss" in ax.get_ylabel() or "MSE" in ax.get_ylabel()]
    assert len(loss_axes) == 2
    for ax in loss_axes:  # the kept epoch's line in both panels
        assert any(list(line.get_xdata()) == [2, 2] for line in ax.get_lines())
    _legend_off_the_axes(fig)
    told = _drawn(training_curve_figure(history, best_epoch=4))
    assert "kept weights (epoch 4)" in [t.get_text() for t in told.legends[0].get_texts()]


def test_units_come_from_the_metadata_else_the_registry():
    nested = {"units": {"outputs": {"h2": "m"}, "inputs": {"q": "-"}}}
    assert signal_units(nested, ["h2"], "outputs") == ["m"]
    assert signal_units({"units": {"ax": "m/s^2", "p": "rad/s"}}, ["ax", "z"], "outputs") == [
        "m/s^2",
        None,
    ]
    from canonid.models.registry import get_system

    tank = get_system("tank")
    registered = {"system": {"name": "tank"}}
    assert signal_units(registered, list(tank.output_names), "outputs") == list(tank.output_units)
    assert signal_units({"system": "nope"}, ["y"], "outputs") == [None]
    assert signal_units({}, ["y"], "outputs") == [None]


def test_tables_and_figures_share_one_name_per_model():
    from canonid.paper import MODEL_LABELS as PAPER_LABELS

    assert PAPER_LABELS is MODEL_LABELS
    assert model_label("mlp") == "Ours (MLP)" and model_label("mlp-new") == "mlp-new"


@pytest.fixture(scope="module")
def dataset_path(tmp_path_factory):
    return siso_dataset_file(tmp_path_factory.mktemp("data"))


def test_train_and_evaluate_write_vector_figures(dataset_path, tmp_path, capsys):
    run = tmp_path / "run"
    argv = ["train", str(dataset_path), "--window", "3", "--epochs", "2", "--out", str(run)]
    assert main([*argv, "--no-progress", "--device", "cpu", "--figure-format", "pdf"]) == 0
    for name in ("training_curve.pdf", "rollouts.pdf"):
        assert (run / name).read_bytes().startswith(MAGIC["pdf"]), name
    assert not list(run.glob("*.png"))
    assert json.loads((run / "metrics.json").read_text())["figure"] == "rollouts.pdf"
    capsys.readouterr()
    assert main(["evaluate", str(run), "--figure-format", "svg"]) == 0
    out = capsys.readouterr().out
    assert evaluated(run, out)["figure"] == "rollouts.svg"
    folder = next((run / "evaluations").iterdir())
    assert folder.name.endswith("-svg")  # the format is one of the evaluation's options
    assert (folder / "rollouts.svg").read_bytes().startswith(MAGIC["svg"])
    assert json.loads((run / "metrics.json").read_text())["figure"] == "rollouts.pdf"
    with pytest.raises(SystemExit):
        main(["evaluate", str(run), "--figure-format", "jpg"])
    assert "--figure-format: invalid choice: 'jpg'" in capsys.readouterr().err


def test_the_bound_figure_has_units_and_no_literal_underscores(tmp_path):
    out = tmp_path / "an"
    argv = ["analyze", "tank", "--windows", "1-2", "--trials", "10", "--boxes", "2000"]
    argv += ["--budget", "3600", "--X", "0.05:5,0.05:5", "--U", "1:3", "--out", str(out)]
    assert main([*argv, "--no-progress", "--figure-format", "svg"]) == 0
    svg = (out / "bound_vs_window.svg").read_text()
    assert svg.startswith("<?xml")
    texts = re.findall(r"<!-- (.*?) -->", svg)  # matplotlib writes each text as a comment
    assert any(t.startswith("state error") and t.endswith("[m]") for t in texts)
    assert "window $\\ell$ [samples]" in texts
    for text in texts:  # underscores only inside math ($…$), where they are subscripts
        assert "_" not in re.sub(r"\$[^$]*\$", "", text), text


def test_inline_markdown_becomes_html():
    assert inline_html("Profile **tiny**, stage `train`") == (
        "Profile <strong>tiny</strong>, stage <code>train</code>"
    )
    assert inline_html("*a* 2*3*4 `x**y**` <b>") == (
        "<em>a</em> 2*3*4 <code>x**y**</code> &lt;b&gt;"
    )


def test_the_html_report_has_no_raw_markdown(tmp_path):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2, 2))
    fig.subplots().plot([0, 1])
    for fmt in ("svg", "pdf"):
        fig.savefig(tmp_path / f"f.{fmt}", format=fmt)
    report = Report("canonid **report**")
    report.paragraph("Profile **tiny** (stages `train` and `reproduce`)")
    report.table(["ℓ", "**MSE**"], [[5, "`1e-4`"]], caption="against *measured* y")
    report.figure(tmp_path / "f.svg", "a *vector* figure")
    report.figure(tmp_path / "f.pdf", "a PDF")
    page = report.to_html(tmp_path)
    visible = re.sub(r"<[^>]+>", "", re.sub(r'src="[^"]*"', "", page))
    assert "**" not in visible and "`" not in visible
    assert "<table>" in page and "<caption>against <em>measured</em> y</caption>" in page
    assert "data:image/svg+xml;base64," in page and '<a href="f.pdf">f.pdf</a>' in page


def _starts(path, fmt: str) -> bool:
    """``path`` holds a figure in ``fmt``: a PDF's magic, an SVG's ``<svg`` element."""
    data = path.read_bytes()
    return data.startswith(MAGIC[fmt]) and (fmt != "svg" or b"<svg" in data)


def test_reduce_writes_every_figure_in_the_format_asked(dataset_path, tmp_path):
    run = tmp_path / "run"
    argv = ["train", str(dataset_path), "--window", "3", "--epochs", "2", "--out", str(run)]
    assert main([*argv, "--no-progress", "--device", "cpu"]) == 0
    one = tmp_path / "one"
    argv = ["reduce", str(run), "--profile", "tiny", "--epochs", "2", "--device", "cpu"]
    argv += ["--no-progress"]
    assert main([*argv, "--compression", "0.5", "--out", str(one), "--figure-format", "pdf"]) == 0
    for name in ("training_curve", "rollouts", "reduced_vs_full"):
        assert _starts(one / f"{name}.pdf", "pdf"), name
    assert not list(one.glob("*.png"))
    study = tmp_path / "study"
    sweep = ["--sweep", "--rates", "0.5", "--seeds", "1", "--out", str(study)]
    assert main([*argv, *sweep, "--figure-format", "svg"]) == 0
    assert _starts(study / "heatmap.svg", "svg") and _starts(study / "reduced_mse.svg", "svg")
    assert not list(study.rglob("*.png"))


def test_generate_plots_in_the_format_asked(tmp_path):
    out = tmp_path / "tank"
    argv = ["generate", "tank", "--out", str(out), "--n-train", "1", "--n-val", "1", "--n-test"]
    assert main([*argv, "1", "--no-progress", "--plot", "--figure-format", "svg"]) == 0
    assert _starts(out / "flights.svg", "svg") and not (out / "flights.png").exists()


def test_benchmark_writes_its_figures_in_the_format_asked_and_keeps_the_option(tmp_path, capsys):
    from test_benchmarks import write_benchmark

    write_benchmark("cascaded-tanks", tmp_path / "files")
    run = tmp_path / "run"
    argv = ["benchmark", "cascaded-tanks", "--dir", str(tmp_path / "files"), "--out", str(run)]
    argv += ["--profile", "tiny", "--threads", "1", "--no-progress", "--epochs", "1"]
    assert main([*argv, "--figure-format", "pdf"]) == 0
    parts = json.loads((run / "benchmark.json").read_text())["scores"]
    names = ["training_curve", "rollouts", *(f"benchmark-{p['test']}" for p in parts)]
    assert all(_starts(run / f"{name}.pdf", "pdf") for name in names)
    assert not list(run.glob("*.png"))
    capsys.readouterr()
    assert main([*argv, "--train-args=--figure-format svg"]) == 1  # the benchmark's own option
    assert "--figure-format set by canonid benchmark itself" in capsys.readouterr().err


def test_reproduce_jobs_follow_its_figure_format(tmp_path):
    import canonid.reproduce as rp

    info = rp.DatasetInfo("tank", tmp_path / "d.npz", {}, "abc", {}, reused=False, seconds=0.0)
    settings = rp.settings_from_profile("tiny", out=tmp_path, figure_format="svg")
    jobs = rp.plan_jobs(settings, {"tank": info})
    assert jobs and all(job.figure_format == "svg" for job in jobs)
    png = rp.plan_jobs(rp.settings_from_profile("tiny", out=tmp_path), {"tank": info})
    assert [job.recipe() for job in jobs] == [job.recipe() for job in png]  # a finished job stays
