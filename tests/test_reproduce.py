"""``canonid reproduce`` on the tiny profile: the report, the same table serially and on a
2-worker Dask cluster, resumption that never redoes a finished job, and the column of canonid's
defaults beside the paper's model."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import shutil
from pathlib import Path

import pytest

import canonid.reproduce as rp
from canonid.cli import main
from canonid.kernel.errors import CheckpointError, DataError
from canonid.learning.training import OptionError
from canonid.paper import TABLE1
from canonid.reproduce import reproduce, settings_from_profile
from canonid.reproduce_jobs import RESULT_FILE, JobOutcome, finished, store
from canonid.reproduce_report import column_label, system_label
from canonid.runner import JobsFailedError


def _results(out: Path) -> dict[str, tuple[bytes, int]]:
    """Every job's result file (Table 1, analysis, reductions) and model weights: bytes and
    modification time (ns)."""
    files = [
        p for name in (RESULT_FILE, "reduction.json", "weights.pt") for p in out.glob(f"**/{name}")
    ]
    return {str(p.relative_to(out)): (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(files)}


def _table(out: Path) -> list[dict]:
    return json.loads((out / "reproduction.json").read_text())["table1"]


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """One serial tiny reproduction through the command line."""
    out = tmp_path_factory.mktemp("serial") / "repro"
    code = main(["reproduce", "--profile", "tiny", "--out", str(out), "--no-progress"])
    assert code == 0
    return out


@pytest.mark.slow
def test_report_sets_every_cell_beside_the_paper_and_links_exist(serial):
    md = (serial / "report.md").read_text()
    data = json.loads((serial / "reproduction.json").read_text())
    cells = data["table1"]
    assert {(c["model"], c["window"], c["options"]) for c in cells} == {
        ("mlp", 5, "paper"),
        ("classic-gru", 5, "paper"),
        ("mlp", 5, "defaults"),
    }
    scale = TABLE1["tank"].scale
    for c in cells:
        assert c["paper"] == pytest.approx(
            TABLE1["tank"].values[c["model"]][0] * scale
        )  # ℓ = 5 is the first column
        assert c["mean"] > 0 and c["mean_clean"] > 0 and c["std"] is None and c["seeds"] == 1
        assert f"{c['mean'] / scale:.3g}" in md and f"{c['paper'] / scale:.3g}" in md
    assert "profile tiny" in md and "Machine:" in md and "load average" in md
    assert "against measured y" in md and "against noise-free y_clean" in md
    # the column of canonid's defaults, labelled, with finite numbers in both tables and pages
    html = (serial / "report.html").read_text()
    (defaults,) = [c for c in cells if c["options"] == "defaults"]
    assert math.isfinite(defaults["mean"]) and math.isfinite(defaults["mean_clean"])
    for page in (md, html):
        assert "Ours (MLP), paper options" in page and "Ours (MLP), canonid defaults" in page
        assert page.count(f"{defaults['mean'] / scale:.3g}") >= 1
    header = next(line for line in md.splitlines() if line.startswith("| ℓ | Classic GRU"))
    assert header.split(" | ")[1:] == [
        "Classic GRU",
        "paper",
        "Ours (MLP), paper options",
        "paper",
        "Ours (MLP), canonid defaults |",
    ]
    assert "<th>Ours (MLP), canonid defaults</th>" in html
    assert "network: Ours (MLP), canonid defaults" in md  # its options in the Budget table
    for target in re.findall(r"\]\(([^)]+)\)", md):
        assert (serial / target).exists(), target
    assert html.count("data:image/png;base64,") == md.count("![")  # figures inlined
    (row,) = data["compression"]["tank"]["rows"]  # the tiny study: one run, one rate
    assert row["window"] == 5 and row["compression"] == 0.5 and row["latent_dim"] < row["state_dim"]
    kinds = sorted(j["kind"] for j in data["jobs"])
    assert kinds == ["analysis", "train", "train", "train"]
    checks = data["learned_checks"]["tank"]
    (residual,) = checks["residual"]  # Table 1's MLP (canonical) at the analysed window
    assert residual["model"] == "mlp" and residual["window"] == 5
    assert residual["run"].endswith("mlp-l5-s0")
    assert residual["rows"] + residual["excluded"] > 0
    (probe,) = checks["probe"]
    assert probe["window"] == 5 and probe["test_rows"] == residual["rows"] + residual["excluded"]


@pytest.mark.slow
def test_resume_of_a_finished_reproduction_runs_nothing(serial, capsys):
    before = _results(serial)
    assert main(["reproduce", "--profile", "tiny", "--out", str(serial), "--resume"]) == 0
    assert "0 run now, 4 already finished" in capsys.readouterr().out
    assert "runs/tank/mlp-defaults-l5-s0/result.json" in before  # the defaults' job too
    assert _results(serial) == before


@pytest.mark.slow
def test_existing_output_needs_resume(serial, capsys):
    assert main(["reproduce", "--profile", "tiny", "--out", str(serial)]) == 1
    assert "--resume" in capsys.readouterr().err


@pytest.mark.slow
def test_two_dask_workers_give_the_same_table(serial, tmp_path):
    out = tmp_path / "dask"
    shutil.copytree(serial / "data", out / "data")  # reused: same configuration
    settings = settings_from_profile("tiny", out=out, workers=2, progress=False)
    result = reproduce(settings)
    assert all(d.reused for d in result.datasets.values())
    assert result.jobs_run == 4
    assert _table(out) == _table(serial)


@pytest.mark.slow
def test_interrupted_run_resumes_without_redoing_finished_jobs(tmp_path, monkeypatch):
    out = tmp_path / "repro"
    calls: list[str] = []
    real = rp.run_job

    def interrupt_second(job):
        calls.append(job.name)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(job)

    monkeypatch.setattr(rp, "run_job", interrupt_second)
    with pytest.raises(KeyboardInterrupt):
        reproduce(settings_from_profile("tiny", out=out, progress=False))
    finished = _results(out)
    assert list(finished) == ["analysis/tank/result.json"]  # the one job done before Ctrl-C

    with pytest.raises(CheckpointError, match="--resume"):
        reproduce(settings_from_profile("tiny", out=out, progress=False))

    calls.clear()
    monkeypatch.setattr(rp, "run_job", lambda job: (calls.append(job.name), real(job))[1])
    result = reproduce(settings_from_profile("tiny", out=out, progress=False, resume=True))
    assert sorted(calls) == [
        "tank classic-gru ℓ=5 seed 0",
        "tank mlp (canonid defaults) ℓ=5 seed 0",
        "tank mlp ℓ=5 seed 0",
    ]
    assert result.jobs_run == 3 and len(result.outcomes) == 4
    after = _results(out)
    assert after["analysis/tank/result.json"] == finished["analysis/tank/result.json"]


def test_a_folder_of_another_recipe_is_refused(tmp_path):
    folder = tmp_path / "job"
    store("train", "x", folder, {"seed": 0}, {"rollout_mse": 1.0})
    assert finished(folder, {"seed": 0}).result == {"rollout_mse": 1.0}
    with pytest.raises(CheckpointError, match="seed"):
        finished(folder, {"seed": 1})


@pytest.mark.slow
def test_a_failing_job_is_retried_once_and_reported(tmp_path, monkeypatch):
    out = tmp_path / "repro"
    calls: list[str] = []
    real = rp.run_job

    def classic_gru_fails(job):
        calls.append(job.name)
        if "classic-gru" in job.name:
            raise RuntimeError("simulated failure")
        return real(job)

    monkeypatch.setattr(rp, "run_job", classic_gru_fails)
    settings = settings_from_profile("tiny", out=out, progress=False)
    with pytest.raises(JobsFailedError, match="1 of 4 jobs failed") as exc:
        reproduce(settings)
    assert calls.count("tank classic-gru ℓ=5 seed 0") == 2  # the first try and one retry
    assert "simulated failure" in exc.value.failures[0].error
    md = (out / "report.md").read_text()
    assert "Failed jobs" in md and "simulated failure" in md
    cells = json.loads((out / "reproduction.json").read_text())["table1"]
    assert sorted(c["model"] for c in cells) == ["mlp", "mlp"]  # the finished jobs are kept


def _outcome(model: str, window: int, seed: int, mse: float, **more: str) -> JobOutcome:
    recipe = {"system": "tank", "model": model, "window": window, "seed": seed, **more}
    result = {"rollout_mse": mse, "rollout_mse_clean": mse / 2}
    return JobOutcome("train", f"{model} {window} {seed}", "f", recipe, result, ran=True)


def test_table_rows_are_mean_and_sample_spread_over_seeds():
    cells = rp.table1_rows(
        [
            _outcome("mlp", 5, 0, 1.0),
            _outcome("mlp", 5, 1, 3.0),
            _outcome("mlp", 7, 0, 2.0),
            _outcome("mlp", 5, 0, 0.5, options="defaults"),
            JobOutcome("analysis", "a", "f", {"system": "tank"}, {}, ran=True),
        ]
    )
    (defaults,) = [c for c in cells if c.options == "defaults"]  # a column of its own
    assert (defaults.window, defaults.mean, defaults.seeds) == (5, 0.5, 1)
    # beside the paper's value of the same model
    assert defaults.paper == pytest.approx(TABLE1["tank"].values["mlp"][0] * TABLE1["tank"].scale)
    by_window = {c.window: c for c in cells if c.options == "paper"}
    assert set(by_window) == {5, 7}
    five = by_window[5]
    assert (five.mean, five.std, five.seeds) == (2.0, pytest.approx(2**0.5), 2)
    assert (five.mean_clean, five.std_clean) == (1.0, pytest.approx(2**0.5 / 2))
    assert five.paper == pytest.approx(TABLE1["tank"].values["mlp"][0] * TABLE1["tank"].scale)
    assert by_window[7].std is None and by_window[7].paper is None  # one seed; not in the paper


@pytest.mark.slow
def test_quadrotor_reproduction_runs_end_to_end_and_says_what_is_out_of_reach(tmp_path):
    """``reproduce --systems quadrotor`` on the tiny profile: simulated data, Table 1, the
    analysis (sampled bounds; the certified side labelled out of reach) and the compression."""
    out = tmp_path / "quad"
    argv = ["reproduce", "--profile", "tiny", "--systems", "quadrotor", "--out", str(out)]
    assert main([*argv, "--no-progress", "--device", "cpu"]) == 0
    data = json.loads((out / "reproduction.json").read_text())
    assert {(c["system"], c["model"]) for c in data["table1"]} == {
        ("quadrotor", "mlp"),
        ("quadrotor", "classic-gru"),
    }
    assert all(c["mean"] > 0 for c in data["table1"])
    analysis = json.loads((out / "analysis" / "quadrotor" / RESULT_FILE).read_text())["result"]
    (row,) = analysis["windows"]
    assert row["window"] == 2 and row["gamma_f"][0] > 0 and row["alpha"] == [0.0, 0.0]
    assert any("α_ℓ = 0 exactly" in line for line in analysis["limitations"])
    md = (out / "report.md").read_text()
    assert "3D Drone (simulated stand-in vs real data in the paper)" in md
    assert "Certified bounds out of reach" in md and "why (quadrotor)" in md
    assert data["compression"]["quadrotor"]["rows"]


def test_quadrotor_is_labelled_as_a_simulated_stand_in():
    assert system_label("quadrotor") == "3D Drone (simulated stand-in vs real data in the paper)"
    assert system_label("tank") == "Tank" and system_label("linear") == "linear"


def test_settings_refuse_unknown_systems_models_and_windows(tmp_path):
    with pytest.raises(DataError, match="no data scenario"):
        settings_from_profile("tiny", out=tmp_path, systems=["linear"])
    with pytest.raises(OptionError, match="unknown model"):
        settings_from_profile("tiny", out=tmp_path, models=["mlp", "nope"])
    with pytest.raises(OptionError, match="windows"):
        settings_from_profile("tiny", out=tmp_path, windows=[0])
    with pytest.raises(OptionError, match="repeats"):
        settings_from_profile("tiny", out=tmp_path, windows=[5, 5])


def test_the_job_list_depends_on_the_settings_only(tmp_path):
    info = rp.DatasetInfo("tank", tmp_path / "d.npz", {}, "abc", {}, reused=False, seconds=0.0)
    plans = [
        rp.plan_jobs(settings_from_profile("tiny", out=tmp_path, workers=w), {"tank": info})
        for w in (0, 2)
    ]
    assert plans[0] == plans[1]
    assert [type(j).__name__ for j in plans[0]] == ["AnalysisJob", *["TrainJob"] * 3]


def test_table1_trains_as_measured_without_the_quick_profiles_clipping(tmp_path):
    """The quick train stage clips gradients; its reproduce stage switches that off with an
    explicit None (train_options alone skips None), so Table 1 stays as it was measured."""
    from canonid.profiles import train_options

    assert train_options("quick").grad_clip is not None
    info = rp.DatasetInfo("tank", tmp_path / "d.npz", {}, "abc", {}, reused=False, seconds=0.0)
    jobs = rp.plan_jobs(settings_from_profile("quick", out=tmp_path), {"tank": info})
    trains = [j for j in jobs if type(j).__name__ == "TrainJob" and j.options == "paper"]
    assert trains and all(j.train_options["grad_clip"] is None for j in trains)
    assert all(j.train_options["batch_size"] == 16 for j in trains)


def _quick_tank_jobs(tmp_path: Path, profile: str = "quick", **overrides) -> list:
    info = rp.DatasetInfo("tank", tmp_path / "d.npz", {}, "abc", {}, reused=False, seconds=0.0)
    settings = settings_from_profile(profile, out=tmp_path, systems=["tank"], **overrides)
    return rp.plan_jobs(settings, {"tank": info})


def test_the_quick_tank_reproduction_trains_canonids_defaults_beside_table1(tmp_path):
    """`make demo`'s job list: Table 1 with the paper's model as measured, plus one job of
    canonid's defaults (Ours (MLP) at ℓ = 10: what `canonid train` trains) started right after
    the analysis, in a folder of its own."""
    from canonid.learning.presets import DEFAULT_NET_OPTIONS, PAPER_NET_OPTIONS
    from canonid.profiles import train_options

    jobs = _quick_tank_jobs(tmp_path)
    (defaults,) = [j for j in jobs if getattr(j, "options", None) == "defaults"]
    assert jobs.index(defaults) == 1  # the longest training job starts first
    assert (defaults.model, defaults.window, defaults.seed) == ("mlp", 10, 0)
    assert defaults.net_options == DEFAULT_NET_OPTIONS["mlp"]
    assert defaults.train_options == train_options("quick", seed=0, device="auto").to_dict()
    assert Path(defaults.folder) == tmp_path.resolve() / "runs" / "tank" / "mlp-defaults-l10-s0"
    assert defaults.recipe()["options"] == "defaults"
    paper = [j for j in jobs if getattr(j, "options", None) == "paper"]
    assert len(paper) == 10  # 5 models × ℓ = 10, 5, as before
    # a paper job's recipe is what it was before the defaults' column, so an older demo resumes
    assert all("options" not in j.recipe() for j in paper)
    assert all(Path(j.folder).name == f"{j.model}-l{j.window}-s0" for j in paper)
    assert [j.net_options for j in paper if j.model == "mlp"] == [PAPER_NET_OPTIONS["mlp"]] * 2


@pytest.mark.parametrize(
    ("profile", "overrides"),
    [
        ("quick", {"windows": [5]}),  # the defaults' window is not in this run
        ("quick", {"models": ["masti"]}),  # nor its model
        ("paper", {}),  # the paper profile has no defaults' column
    ],
)
def test_the_defaults_column_follows_the_runs_models_and_windows(tmp_path, profile, overrides):
    jobs = _quick_tank_jobs(tmp_path, profile, **overrides)
    trains = [j for j in jobs if type(j).__name__ == "TrainJob"]
    assert trains and all(j.options == "paper" for j in trains)


def test_a_train_job_names_its_options_or_refuses_others(tmp_path):
    (job,) = [j for j in _quick_tank_jobs(tmp_path) if getattr(j, "options", "") == "defaults"]
    assert job.name == "tank mlp (canonid defaults) ℓ=10 seed 0"
    with pytest.raises(OptionError, match="options must be 'paper' or 'defaults'"):
        dataclasses.replace(job, options="mine")


def test_columns_are_labelled_by_the_options_they_were_trained_with():
    assert column_label("mlp") == "Ours (MLP), paper options"
    assert column_label("mlp", "defaults") == "Ours (MLP), canonid defaults"
    assert column_label("classic-gru") == "Classic GRU"  # one set of options: no suffix


def test_the_table1_figure_names_both_mlp_columns_in_its_legend():
    from canonid.reproduce_report import plot_table1

    def cell(model: str, window: int, options: str = "paper") -> rp.Table1Cell:
        return rp.Table1Cell("tank", model, window, 1, 1e-4, None, 1e-4, None, None, options)

    cells = [cell("mlp", 5), cell("mlp", 10), cell("gru", 10), cell("mlp", 10, "defaults")]
    fig = plot_table1(cells, "tank")
    labels = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    assert sorted(labels) == sorted(
        [
            "Ours (GRU) (this run)",
            "Ours (GRU) (paper)",
            "Ours (MLP), paper options (this run)",
            "Ours (MLP) (paper)",
            "Ours (MLP), canonid defaults (this run)",
        ]
    )
