"""The main user path end to end, each command exactly as a user types it:
CSV in → ``train --val`` → ``evaluate --data`` → ``analyze --run``; and ``train --resume``
refusing what it would otherwise ignore."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from cli_helpers import evaluated, one_line_error

from canonid.cli import main
from canonid.datagen.loaders import data_checksum
from canonid.models.registry import get_system

DT = 2.0
RECORD = 120


def _write_tank_csv(path, seeds, *, T=RECORD, noise=0.005):
    """Tank records under pump levels held for 8 samples, one experiment per seed, rows of each
    experiment contiguous; columns run, time, pump, level (the lower tank's level)."""
    system = get_system("tank")
    rows = ["run,time,pump,level"]
    for seed in seeds:
        rng = np.random.default_rng(seed)
        u = np.repeat(rng.uniform(1, 3, size=(T // 8 + 1, 1)), 8, axis=0)[:T]
        y = system.simulate(rng.uniform(0.5, 2, 2), u).y
        y = y + rng.uniform(-noise, noise, size=y.shape)
        rows += [f"r{seed},{t * DT},{float(u[t, 0])!r},{float(y[t, 0])!r}" for t in range(T)]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="module")
def csv_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("csv")
    return (
        _write_tank_csv(folder / "train.csv", [1, 2, 3]),
        _write_tank_csv(folder / "val.csv", [4]),
        _write_tank_csv(folder / "test.csv", [5, 6]),
    )


CSV_OPTIONS = ["--inputs", "pump", "--outputs", "level", "--experiment-column", "run"]
QUICK = ["--epochs", "2", "--device", "cpu", "--no-progress"]


@pytest.fixture(scope="module")
def trained(csv_files, tmp_path_factory):
    """``canonid train train.csv --val val.csv …`` (the run is shared by the tests below; a
    narrow network, which the analysis of the learned model bounds in seconds)."""
    train_csv, val_csv, _ = csv_files
    run = tmp_path_factory.mktemp("runs") / "mlp"
    argv = ["train", str(train_csv), "--val", str(val_csv), *CSV_OPTIONS, "--dt", str(DT)]
    argv += ["--model", "mlp", "--window", "3", "--hidden", "32,32"]
    assert main([*argv, *QUICK, "--out", str(run)]) == 0
    return run


def test_train_with_a_val_csv_scores_the_val_file(trained, csv_files):
    metrics = json.loads((trained / "metrics.json").read_text())
    assert metrics["data"]["split"] == "val" and metrics["data"]["n_trajectories"] == 1
    assert metrics["data"]["path"] == str(csv_files[1].resolve())  # the file it scored
    recipe = json.loads((trained / "run.json").read_text())
    assert recipe["val"] == str(csv_files[1]) and recipe["data_options"]["dt"] == DT
    config = json.loads((trained / "config.json").read_text())
    assert config["info"]["data"]["splits"] == {"train": 3, "val": 1}


def test_evaluate_rebuilds_the_runs_split_and_keeps_the_held_out_score(trained, csv_files, capsys):
    before = (trained / "metrics.json").read_bytes()
    written = json.loads(before)
    capsys.readouterr()
    assert main(["evaluate", str(trained)]) == 0
    out = capsys.readouterr().out
    again = evaluated(trained, out)
    assert again["data"]["split"] == "val" and "[val]" in out
    assert again["data"]["path"] == written["data"]["path"] == str(csv_files[1].resolve())
    assert again["rollout_mse"] == pytest.approx(written["rollout_mse"], rel=1e-12)
    assert main(["evaluate", str(trained), "--split", "train"]) == 0
    scored = evaluated(trained, capsys.readouterr().out)["data"]
    assert scored["split"] == "train" and scored["n_trajectories"] == 3
    assert (trained / "metrics.json").read_bytes() == before


def test_evaluate_data_reuses_the_runs_csv_options_and_names_the_split_all(
    trained, csv_files, capsys
):
    test_csv = csv_files[2]
    capsys.readouterr()
    assert main(["evaluate", str(trained), "--data", str(test_csv)]) == 0
    out = capsys.readouterr().out
    assert f"{test_csv} [all]" in out
    metrics = evaluated(trained, out)
    checksum = data_checksum(test_csv)
    assert metrics["data"] == {
        "path": str(test_csv),
        "split": "all",
        "n_trajectories": 2,
        "sha256": checksum,
    }
    assert f"evaluations/{test_csv.stem}-{checksum[:8]}-all/" in out
    assert metrics["evaluation"]["data_options"]["dt"] == DT
    assert metrics["n_rollouts"] == 2 * (RECORD - 3 - 100 + 1)
    code = main(["evaluate", str(trained), "--data", str(test_csv), "--dt", "1.0"])
    one_line_error(capsys, code, "dt = 1 s was given, but time column 'time' steps by 2 s")
    off = ["--time-column", "none"]  # the rows as samples every 1 s: not the run's sampling time
    code = main(["evaluate", str(trained), "--data", str(test_csv), "--dt", "1.0", *off])
    one_line_error(capsys, code, str(test_csv), "dt = 1 s, the run's is 2 s")
    code = main(["evaluate", str(trained), "--dt", "1.0"])
    one_line_error(capsys, code, "--dt apply to --data FILE")


def test_a_held_out_csv_without_the_experiment_column_is_scored_beside_training(
    trained, tmp_path, capsys, caplog
):
    """The run recorded --experiment-column run: a held-out CSV without that column is refused
    in one line naming the inherited option and the way out, which scores it in a folder of
    its own; asked again, the evaluation is read back, and training's files stay."""
    before = {p: p.read_bytes() for p in trained.glob("*") if p.is_file()}
    held_out = tmp_path / "held_out.csv"
    held_out.write_text(
        "time,pump,level\n" + "".join(f"{t * DT},2.0,{0.5 + 0.001 * t}\n" for t in range(80))
    )
    code = main(["evaluate", str(trained), "--data", str(held_out)])
    one_line_error(capsys, code, "no column(s) ['run']", "--experiment-column run", "none")
    argv = ["evaluate", str(trained), "--data", str(held_out), "--experiment-column", "none"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    first = evaluated(trained, out)
    assert first["data"]["path"] == str(held_out) and first["data"]["n_trajectories"] == 1
    assert first["evaluation"]["data_options"]["experiment_column"] == ""
    folder = next(p for p in (trained / "evaluations").iterdir() if "held_out" in p.name)
    assert (folder / "rollouts.png").stat().st_size > 0
    assert folder.name.startswith(f"held_out-{data_checksum(held_out)[:8]}-all-csv")
    # the same evaluation again: read back, nothing rewritten
    stamp = (folder / "metrics.json").stat().st_mtime_ns
    assert main(argv) == 0
    assert "already evaluated" in capsys.readouterr().out
    assert (folder / "metrics.json").stat().st_mtime_ns == stamp
    # dt comes from the time column (2 s), so none was needed; a restart of it warns
    restarted = tmp_path / "two_records.csv"
    body = "".join(f"{t * DT},2.0,{0.5 + 0.001 * t}\n" for t in range(60))
    restarted.write_text("time,pump,level\n" + body + body)
    argv = ["evaluate", str(trained), "--data", str(restarted), "--experiment-column", "none"]
    assert main(argv) == 0
    warned = [r.getMessage() for r in caplog.records if "goes back" in r.getMessage()]
    assert warned and f"{restarted}, line 62: time column 'time'" in warned[0]
    assert "--experiment-column" in warned[0]
    after = {p: p.read_bytes() for p in trained.glob("*") if p.is_file()}
    assert after == before


def test_evaluate_data_names_the_signals_outside_the_training_span(
    trained, csv_files, tmp_path, capsys
):
    """Training records each signal's span over the training records; a held-out CSV whose pump
    runs above it on half its samples is scored, and the scores say so in one line and in
    metrics.json (the level, held inside its span, is not named)."""
    table = np.genfromtxt(csv_files[0], delimiter=",", names=True, dtype=None, encoding=None)
    config = json.loads((trained / "config.json").read_text())
    spans = config["info"]["training_range"]
    assert spans == {
        "inputs": [[float(table["pump"].min()), float(table["pump"].max())]],
        "outputs": [[float(table["level"].min()), float(table["level"].max())]],
    }
    (lo, hi), level = spans["inputs"][0], sum(spans["outputs"][0]) / 2
    high = hi + 0.5 * (hi - lo)
    pumps = [high] * 30 + [(lo + hi) / 2] * 30
    beyond = tmp_path / "beyond.csv"
    rows = "".join(f"r9,{t * DT},{p!r},{level!r}\n" for t, p in enumerate(pumps))
    beyond.write_text("run,time,pump,level\n" + rows)
    capsys.readouterr()
    assert main(["evaluate", str(trained), "--data", str(beyond)]) == 0
    out = capsys.readouterr().out
    (entry,) = evaluated(trained, out)["outside_training_range"]
    assert entry["name"] == "pump" and entry["kind"] == "input" and entry["share"] == 0.5
    assert entry["beyond"] == pytest.approx(0.5) and entry["span_high"] == hi
    (line,) = [line for line in out.splitlines() if line.startswith("outside the training range")]
    assert "input pump on 50 % of samples" in line and "level" not in line
    # a pump a twentieth of its span above: kept in metrics.json, not named in the table
    near = tmp_path / "near.csv"
    rows = "".join(
        f"r9,{t * DT},{p!r},{level!r}\n" for t, p in enumerate([hi + 0.04 * (hi - lo)] * 60)
    )
    near.write_text("run,time,pump,level\n" + rows)
    assert main(["evaluate", str(trained), "--data", str(near)]) == 0
    out = capsys.readouterr().out
    (entry,) = evaluated(trained, out)["outside_training_range"]
    assert entry["share"] == 1.0 and entry["beyond"] == pytest.approx(0.04)
    assert "outside the training range" not in out
    assert main(["evaluate", str(trained), "--split", "train"]) == 0  # its own training records
    out = capsys.readouterr().out
    assert evaluated(trained, out)["outside_training_range"] == []
    assert "outside the training range" not in out


def test_train_says_where_validation_does_not_reach_the_training_levels(
    csv_files, tmp_path, capsys
):
    """A validation file whose pump stays at one level: training names the pump, the share of
    training samples off that level, and records it in the model's info; a validation file
    covering the training records (the training file itself) gives no such line."""
    train_csv = csv_files[0]
    narrow = tmp_path / "narrow.csv"
    rows = "".join(f"r9,{t * DT},2.0,{0.8 + 0.001 * t!r}\n" for t in range(RECORD))
    narrow.write_text("run,time,pump,level\n" + rows)
    argv = ["train", str(train_csv), *CSV_OPTIONS, "--dt", str(DT), "--window", "3"]
    argv += ["--hidden", "8,8", "--cubic", "0", "--no-feedthrough", "--epochs", "1"]
    argv += ["--device", "cpu", "--no-progress"]
    assert main([*argv, "--val", str(narrow), "--out", str(tmp_path / "narrow")]) == 0
    out = capsys.readouterr().out
    (line,) = [line for line in out.splitlines() if line.startswith("validation does not reach")]
    assert "input pump on" in line and "validation span [2, 2]" in line
    info = json.loads((tmp_path / "narrow" / "config.json").read_text())["info"]
    pump = next(o for o in info["training_outside_validation"] if o["name"] == "pump")
    table = np.genfromtxt(train_csv, delimiter=",", names=True, dtype=None, encoding=None)
    assert pump["share"] == pytest.approx(np.mean(table["pump"] != 2.0))
    assert main([*argv, "--val", str(train_csv), "--out", str(tmp_path / "same")]) == 0
    assert "validation does not reach" not in capsys.readouterr().out


def test_an_evaluation_of_other_weights_is_not_overwritten(trained, tmp_path, capsys):
    run = tmp_path / "run"
    shutil.copytree(trained, run)
    shutil.rmtree(run / "evaluations", ignore_errors=True)
    assert main(["evaluate", str(run), "--eval-horizon", "20"]) == 0
    first = evaluated(run, capsys.readouterr().out)
    weights = run / "weights.pt"
    weights.write_bytes(weights.read_bytes() + b"\0")  # stands for weights trained further
    folder = next((run / "evaluations").iterdir())
    saved = (folder / "metrics.json").read_bytes()
    code = main(["evaluate", str(run), "--eval-horizon", "20"])
    one_line_error(capsys, code, str(folder), "other weights", "remove that folder")
    assert (folder / "metrics.json").read_bytes() == saved
    assert json.loads(saved) == first


def test_evaluate_help_says_the_csv_options_default_to_the_runs(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "Each option defaults to the one the run recorded in RUN/run.json" in text
    assert "'none' to switch a column off" in text and "--time-column COL|none" in text
    assert text.count("(default: the run's)") == 5


def test_analyze_run_checks_a_csv_trained_tank_model(trained, csv_files, tmp_path, capsys):
    out = tmp_path / "analysis"
    quick = ["--boxes", "40", "--budget", "5", "--no-progress", "--out", str(out)]
    # the shared run says dt = 2 s; the tank samples every 1 s: not the tank's data
    argv = ["analyze", "tank", "--run", str(trained), "--window", "3", "--trials", "5"]
    one_line_error(capsys, main([*argv, *quick]), "sampling time dt 2.0 (the run) vs 1.0 (tank)")
    assert not out.exists()
    # the same CSV at the tank's sampling time; its column names only differ (a warning)
    run = tmp_path / "tank-dt1"
    train_csv, val_csv, _ = csv_files
    fit = ["train", str(train_csv), "--val", str(val_csv), *CSV_OPTIONS, "--dt", "1.0"]
    fit += ["--time-column", "none"]  # the rows as samples every 1 s, not the column's 2 s
    assert main([*fit, "--model", "mlp", "--window", "3", *QUICK, "--out", str(run)]) == 0
    argv = ["analyze", "tank", "--run", str(run), "--window", "3", "--trials", "5"]
    # CSV records carry no noise-free outputs: refused before the analysis runs
    one_line_error(capsys, main([*argv, *quick]), "needs the noise w = y − y_clean", "[val]")
    assert not out.exists()
    # the same records with y_clean, as an .npz the run's options read
    system, rng = get_system("tank"), np.random.default_rng(8)
    u = np.repeat(rng.uniform(1, 3, size=(16, 1)), 8, axis=0)
    clean = system.simulate(np.array([1.0, 1.5]), u).y
    test_npz = tmp_path / "test.npz"
    np.savez(test_npz, u=u, y=clean + rng.uniform(-0.005, 0.005, clean.shape), y_clean=clean)
    assert main([*argv, "--data", str(test_npz), *quick]) == 0
    learned = json.loads((out / "analysis.json").read_text())["learned"]
    assert learned["window"] == 3 and learned["split"] == "all"
    assert learned["data"] == str(test_npz) and learned["residual"]["rows"] == 128 - 3
    code = main(["analyze", "drone2d", "--run", str(run), "--window", "3", "--no-progress"])
    one_line_error(capsys, code, "number of inputs 1 (the run) vs 2 (drone2d)")


def test_analyze_run_without_a_system_bounds_the_learned_model_alone(trained, tmp_path, capsys):
    # real data have no registered system: `analyze --run RUN` bounds the model's own γ_f
    out = tmp_path / "learned"
    quick = ["--boxes", "20", "--no-progress", "--out", str(out)]
    capsys.readouterr()
    assert main(["analyze", "--run", str(trained), *quick]) == 0
    printed = capsys.readouterr().out
    assert "no registered system, so no α_ℓ" in printed
    body = json.loads((out / "learned_analysis.json").read_text())
    gamma = body["gamma_f"]
    assert f"so γ_f ≤ {gamma['best_upper']:.4g}" in printed  # the better certified bound
    assert body["window"] == 3 and gamma["available"] and gamma["state_dim"] == 6
    assert gamma["lower"]["kind"] == "lower" and gamma["branch_and_bound"]["kind"] == "upper"
    assert gamma["branch_and_bound"]["details"]["boxes"] <= 20 + 64  # the last round's children
    assert 0 < gamma["lower"]["value"] <= gamma["best_upper"]
    one_line_error(capsys, main(["analyze", "--no-progress"]), "give a registered SYSTEM")
    code = main(["analyze", "--run", str(trained), "--window", "5", *quick])
    one_line_error(capsys, code, "the run's model has window ℓ = 3")
    code = main(["analyze", "--run", str(trained), "--X", "0:1", *quick])
    one_line_error(capsys, code, "--X applies to a registered SYSTEM")
    code = main(["analyze", "tank", "--no-progress"])
    one_line_error(capsys, code, "one of --window L or --windows A-B is required")


def test_a_single_csv_record_trains_on_its_head_and_scores_its_tail(tmp_path, capsys):
    data = _write_tank_csv(tmp_path / "one.csv", [7], T=600)
    run = tmp_path / "run"
    argv = ["train", str(data), "--inputs", "pump", "--outputs", "level", "--dt", str(DT)]
    argv += ["--model", "mlp", *QUICK]
    assert main([*argv, "--window", "3", "--out", str(run)]) == 0
    metrics = json.loads((run / "metrics.json").read_text())
    # the validation part is samples 480…599 (the last 20 %)
    assert metrics["data"]["split"] == "val" and metrics["n_scored_samples"] == 120 - 50
    # records shorter than the default n_init and horizon are scored on what they hold
    short = _write_tank_csv(tmp_path / "short.csv", [8], T=40)
    assert main(["evaluate", str(run), "--data", str(short)]) == 0
    metrics = evaluated(run, capsys.readouterr().out)
    assert metrics["n_init"] == 39 and metrics["rollout_horizon"] == 40 - 3
    # a split too short for the window is refused before any training
    code = main([*argv, "--window", "120", "--out", str(tmp_path / "x")])
    one_line_error(capsys, code, "one.csv", "no candidate window of [120] fits the records")
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--residual"], "--residual cannot change when resuming"),
        (["--no-feedthrough"], "--feedthrough cannot change when resuming"),
        (["--profile", "paper"], "profile: 'quick' there, 'paper' here"),
        (["--val", "other.csv"], "val: "),
        (["--val-fraction", "0.5"], "val_fraction: 0.2 there, 0.5 here"),
        (["--dt", "1.0"], "dt: 2.0 there, 1.0 here"),
    ],
)
def test_resume_refuses_what_it_would_ignore(trained, tmp_path, capsys, extra, needle):
    run = tmp_path / "run"
    shutil.copytree(trained, run)
    before = {p: p.read_bytes() for p in run.rglob("*") if p.is_file()}
    code = main(["train", "--resume", "--out", str(run), "--epochs", "3", "--no-progress", *extra])
    one_line_error(capsys, code, needle)
    assert {p: p.read_bytes() for p in run.rglob("*") if p.is_file()} == before


def test_the_former_resume_run_is_read_with_a_warning(trained, tmp_path, capsys):
    """``--resume RUN`` (before ``--resume --out RUN``): read for one release, with a warning; an
    ``--out`` beside it is refused as before."""
    run = tmp_path / "run"
    shutil.copytree(trained, run)
    before = {p: p.read_bytes() for p in run.rglob("*") if p.is_file()}
    code = main(["train", "--resume", str(run), "--out", "elsewhere", "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    warning = f"canonid train: warning: --resume RUN is deprecated, use --resume --out {run}"
    assert code == 1 and err[0] == warning and len(err) == 2, err
    assert "--out does not apply with --resume" in err[1]
    assert {p: p.read_bytes() for p in run.rglob("*") if p.is_file()} == before


def test_resume_with_the_same_options_and_an_eval_horizon_runs(trained, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(trained, run)
    resume = [
        "train",
        "--resume",
        "--out",
        str(run),
        "--epochs",
        "3",
        "--no-progress",
        "--device",
        "cpu",
    ]
    assert main([*resume, "--dt", str(DT), "--eval-horizon", "20"]) == 0
    assert json.loads((run / "metrics.json").read_text())["rollout_horizon"] == 20


@pytest.mark.slow
def test_analyze_tank_for_windows_3_to_10_on_the_default_sets(tmp_path, capsys):
    """Was `LinAlgError: SVD did not converge`: some sampled ∂O_ℓ/∂x are not finite."""
    argv = ["analyze", "tank", "--windows", "3-10", "--trials", "3", "--boxes", "20"]
    assert main([*argv, "--budget", "5", "--no-progress", "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "Sampled bounds:" in out and "samples have no finite ∂O_ℓ/∂x" in out
    data = json.loads((tmp_path / "a" / "analysis.json").read_text())
    assert data["windows"] == list(range(3, 11))


def test_validation_data_of_another_sampling_time_or_shape_are_refused(csv_files, tmp_path, capsys):
    train_csv = csv_files[0]
    argv = ["train", str(train_csv), *CSV_OPTIONS, "--dt", str(DT), "--model", "mlp"]
    argv += ["--window", "3", *QUICK, "--out", str(tmp_path / "run")]
    other_dt, two_outputs = tmp_path / "dt.npz", tmp_path / "wide.npz"
    np.savez(other_dt, u=np.ones((150, 1)), y=np.ones((150, 1)), dt=1.0)
    np.savez(two_outputs, u=np.ones((150, 1)), y=np.ones((150, 2)))
    one_line_error(capsys, main([*argv, "--val", str(other_dt)]), "dt.npz: holds dt = 1.0")
    code = main([*argv, "--val", str(two_outputs)])
    one_line_error(capsys, code, "wide.npz: 2 output(s) ['y1', 'y2'],", "train.csv's are ['level']")
    assert not (tmp_path / "run").exists()


def test_reduce_scores_records_shorter_than_the_paper_horizon_as_train_does(tmp_path, capsys):
    # 150 samples: the validation tail holds 30, so both score 27-step rollouts (ℓ = 3)
    data = _write_tank_csv(tmp_path / "short.csv", [9], T=150)
    run, red = tmp_path / "run", tmp_path / "red"
    argv = ["train", str(data), "--inputs", "pump", "--outputs", "level", "--dt", str(DT)]
    assert main([*argv, "--model", "mlp", "--window", "3", *QUICK, "--out", str(run)]) == 0
    assert json.loads((run / "metrics.json").read_text())["rollout_horizon"] == 27
    reduce = ["reduce", str(run), "--compression", "0.5", "--epochs", "1", "--device", "cpu"]
    assert main([*reduce, "--no-progress", "--out", str(red)]) == 0
    result = json.loads((red / "reduction.json").read_text())
    assert (result["rollout_horizon"], result["split"]) == (27, "val")
    assert "27-step rollout MSE on the val split" in capsys.readouterr().out
