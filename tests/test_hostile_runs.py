"""A run folder received from someone else is data (issue 29): ``evaluate``, ``export``,
``analyze --run`` and ``train --resume`` read it, and every bad field, mismatched dataset or
option gets one line naming it, a non-zero exit, and nothing written (outside the folder or
half-way). The analysis keeps to its ``--budget`` in every stage; the worker pool closes on
SIGTERM as on Ctrl-C.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from cli_helpers import one_line_error
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st
from learning_helpers import damped_siso, trajectories

import canonid.analysis.lipschitz as lipschitz
from canonid.analysis.enclosure import Enclosure
from canonid.analysis.estimate import Budget, OutOfTime
from canonid.cli import main
from canonid.kernel.dataset import Dataset, Trajectory
from canonid.models.sets import Box

COMMON = ["--epochs", "1", "--no-progress", "--device", "cpu"]


def _dataset(n_train: int, seed: int, *, dt: float, names: tuple[str, str]) -> Dataset:
    system = damped_siso()

    def make(n: int, s: int) -> tuple[Trajectory, ...]:
        return tuple(
            Trajectory(u=t.u, y=t.y, y_clean=t.y_clean)
            for t in trajectories(system, n, 80, noise=0.01, seed=s)
        )

    return Dataset(
        splits={"train": make(n_train, seed), "val": make(1, seed + 1), "test": make(1, seed + 2)},
        dt=dt,
        input_names=(names[0],),
        output_names=(names[1],),
    )


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """A run of Ours (MLP) trained on ``pump``/``level`` at dt = 0.5 s, and data that differ from
    its training data in one way each."""
    root = tmp_path_factory.mktemp("hostile-runs")
    data = _dataset(2, 1, dt=0.5, names=("pump", "level")).save(root / "data" / "dataset.npz")
    _dataset(2, 5, dt=1.0, names=("pump", "level")).save(root / "other-dt" / "dataset.npz")
    _dataset(2, 5, dt=0.5, names=("u", "y")).save(root / "other-names" / "dataset.npz")
    argv = ["train", str(data), "--model", "mlp", "--window", "3", "--hidden", "8,8"]
    assert main([*argv, "--out", str(root / "run"), *COMMON]) == 0
    return root


def _run(root: Path, tmp_path: Path) -> Path:
    """A fresh copy of the trained run (its run.json names the data by absolute path)."""
    return Path(shutil.copytree(root / "run", tmp_path / "run"))


def _edit_json(path: Path, edit) -> None:
    body = json.loads(path.read_text(encoding="utf-8"))
    edit(body)
    path.write_text(json.dumps(body), encoding="utf-8")


def _refused(capsys, argv: list[str], *needles: str) -> str:
    """``canonid ARGV`` exits 1 with one line on stderr holding every needle."""
    return one_line_error(capsys, main(argv), *needles)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


# ------------------------------------------------------------------ fields of the wrong type
def test_a_text_sampling_time_in_config_json_is_one_line(root, tmp_path, capsys):
    run = _run(root, tmp_path)
    _edit_json(run / "config.json", lambda c: c["info"].update(dt="abc"))
    target = tmp_path / "out" / "m.casadi"
    _refused(capsys, ["export", str(run), "--casadi", str(target)], "info.dt", "config.json")
    assert not target.parent.exists()


@pytest.mark.parametrize(
    "spans",
    [
        "wide",
        {"inputs": [[0, 1]]},
        {"inputs": [[0, 1]], "outputs": [[2, 1]]},
        {"inputs": [["a", 1]], "outputs": [[0, 1]]},
        {"inputs": [[0, 1, 2]], "outputs": [[0, 1]]},
    ],
)
def test_a_malformed_training_range_in_config_json_is_one_line(spans, root, tmp_path, capsys):
    run = _run(root, tmp_path)
    assert json.loads((run / "config.json").read_text())["info"]["training_range"]
    _edit_json(run / "config.json", lambda c: c["info"].update(training_range=spans))
    before = _snapshot(run)
    _refused(capsys, ["evaluate", str(run)], "info.training_range", "config.json")
    assert _snapshot(run) == before


@pytest.mark.parametrize("found", ["none", [{"name": "u"}], [{"name": 1, "kind": "input"}]])
def test_a_malformed_record_of_levels_validation_misses_is_one_line(found, root, tmp_path, capsys):
    run = _run(root, tmp_path)
    assert "training_outside_validation" in json.loads((run / "config.json").read_text())["info"]
    _edit_json(run / "config.json", lambda c: c["info"].update(training_outside_validation=found))
    _refused(capsys, ["evaluate", str(run)], "info.training_outside_validation", "config.json")


@pytest.mark.parametrize(
    ("field", "value"), [("data", {"x": 1}), ("window", "five"), ("data_options", {"dt": "x"})]
)
def test_a_run_json_field_of_the_wrong_type_is_one_line(field, value, root, tmp_path, capsys):
    run = _run(root, tmp_path)
    _edit_json(run / "run.json", lambda r: r.update({field: value}))
    before = _snapshot(run)
    _refused(capsys, ["evaluate", str(run)], "run.json", field)
    _refused(capsys, ["export", str(run), "--casadi", str(tmp_path / "m.casadi")], field)
    assert _snapshot(run) == before and not (tmp_path / "m.casadi").exists()


@pytest.mark.parametrize(
    ("field", "edit"),
    [
        ("model", lambda m: m.pop("model")),
        ("rmse", lambda m: m.update(rmse="small")),
        ("rollout_mse_per_output", lambda m: m.update(output_names=["a", "b"])),
        ("clean", lambda m: m.update(clean=3)),
        ("data", lambda m: m.update(data=[])),
        ("n_init", lambda m: m.update(n_init=-1)),
        ("outside_training_range[0]", lambda m: m.update(outside_training_range=[{"name": 1}])),
        ("outside_training_range", lambda m: m.update(outside_training_range="none")),
        ("rollout_mse_per_record", lambda m: m.update(rollout_mse_per_record=5)),
        ("finite", lambda m: m.update(finite="yes")),
        ("evaluation", lambda m: m["evaluation"].update(stride=2)),
    ],
)
def test_a_hand_edited_metrics_json_read_back_by_evaluate_is_one_line(
    field, edit, root, tmp_path, capsys
):
    """``canonid evaluate`` asked again prints the evaluation's stored ``metrics.json``: a field
    of the wrong type there is named, not a traceback, and nothing is rewritten."""
    run = _run(root, tmp_path)
    assert main(["evaluate", str(run)]) == 0
    (stored,) = (run / "evaluations").glob("*/metrics.json")
    capsys.readouterr()
    assert main(["evaluate", str(run)]) == 0  # the same evaluation: read back, printed
    assert "already evaluated" in capsys.readouterr().out
    _edit_json(stored, edit)
    before = _snapshot(run)
    _refused(capsys, ["evaluate", str(run)], str(stored), f"'{field}'")
    assert _snapshot(run) == before


@pytest.mark.parametrize(
    "command",
    [
        ["evaluate"],
        ["analyze", "--no-progress", "--run"],
        ["export", "--casadi", "OUT", "--"],
        ["reduce", "--compression", "0.5", "--no-progress"],
    ],
)
def test_a_folder_that_holds_no_model_is_named_so(command, tmp_path, capsys):
    """A mistyped or wrong folder: "not found", or the folder and the missing config.json with
    what to give instead, one line, nothing written."""
    (tmp_path / "notes").mkdir()
    argv = [str(tmp_path / "m.casadi") if a == "OUT" else a for a in command]
    _refused(capsys, [*argv, str(tmp_path / "typo")], "folder not found", "typo")
    _refused(capsys, [*argv, str(tmp_path / "notes")], "holds no", "--out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes"]


# ------------------------------------------------------------------ data that do not fit the run
def _with_empty(data: Dataset, split: str) -> Dataset:
    return Dataset(
        splits={**data.splits, split: ()},
        dt=data.dt,
        input_names=data.input_names,
        output_names=data.output_names,
    )


def test_a_dataset_without_training_records_is_refused_in_one_line(tmp_path, capsys):
    data = _dataset(2, 1, dt=0.5, names=("pump", "level"))
    path = _with_empty(data, "train").save(tmp_path / "empty" / "dataset.npz")
    out = tmp_path / "run"
    argv = ["train", str(path), "--window", "3", "--hidden", "8,8", "--out", str(out), *COMMON]
    _refused(capsys, argv, str(path), "'train' split holds no record")
    assert not out.exists()
    other = _with_empty(data, "val").save(tmp_path / "no-val" / "dataset.npz")
    argv = ["train", str(other), "--val", str(other), *argv[2:]]  # a --val file of no record
    _refused(capsys, argv, str(other), "validation split holds no record")
    assert not out.exists()


def test_evaluate_names_an_empty_split_and_the_splits_that_hold_records(root, tmp_path, capsys):
    run = _run(root, tmp_path)
    data = _with_empty(_dataset(2, 5, dt=0.5, names=("pump", "level")), "test")
    path = _with_empty(data, "val").save(tmp_path / "empty" / "dataset.npz")
    argv = ["evaluate", str(run), "--data", str(path)]
    _refused(capsys, argv, str(path), "'test' split holds no record", "['train']", "--split")
    _refused(capsys, [*argv, "--split", "val"], "split 'val' holds no record", "['train']")
    assert main([*argv, "--split", "train"]) == 0


def test_an_empty_validation_split_is_cut_off_the_training_records_as_none_is(tmp_path):
    """``canonid generate --n-val 0``: the dataset's ``val`` split is empty, so the run validates
    on a part cut off its training records, exactly as for data without a ``val`` split."""
    data = _dataset(4, 1, dt=0.5, names=("pump", "level"))
    empty = _with_empty(data, "val").save(tmp_path / "empty-val" / "dataset.npz")
    splits = {k: v for k, v in data.splits.items() if k != "val"}
    none = Dataset(splits=splits, dt=0.5, input_names=("pump",), output_names=("level",))
    none = none.save(tmp_path / "no-val" / "dataset.npz")
    for path, out in ((empty, "a"), (none, "b")):
        argv = ["train", str(path), "--window", "3", "--hidden", "8,8", *COMMON]
        assert main([*argv, "--out", str(tmp_path / out)]) == 0
    a, b = (json.loads((tmp_path / o / "config.json").read_text()) for o in "ab")
    assert a["info"]["training"]["best_val_loss"] == b["info"]["training"]["best_val_loss"]
    assert (tmp_path / "a" / "weights.pt").read_bytes() == (
        tmp_path / "b" / "weights.pt"
    ).read_bytes()


def test_export_refuses_data_of_another_sampling_time(root, tmp_path, capsys):
    target = tmp_path / "m.casadi"
    argv = ["export", str(root / "run"), "--casadi", str(target)]
    _refused(capsys, [*argv, "--data", str(root / "other-dt")], "dt = 1", "0.5")
    assert not target.exists()


def test_data_with_other_signal_names_are_refused_unless_the_columns_are_named(
    root, tmp_path, capsys
):
    run = _run(root, tmp_path)
    before = _snapshot(run)
    other = str(root / "other-names")
    _refused(capsys, ["evaluate", str(run), "--data", other], "['u']", "['pump']", "--inputs")
    export = ["export", str(run), "--casadi", str(tmp_path / "m.casadi"), "--data", other]
    err = _refused(capsys, export, "['u']", "['pump']", "leave out --data")
    assert "--inputs" not in err  # export has no --inputs (issue 54)
    assert _snapshot(run) == before
    # the same signals as CSV columns, chosen by name: the user's statement, accepted
    ds = _dataset(1, 7, dt=0.5, names=("u", "y"))
    tr = ds.split("train")[0]
    csv = tmp_path / "renamed.csv"
    rows = "\n".join(f"{u:.17g},{y:.17g}" for u, y in zip(tr.u[:, 0], tr.y[:, 0]))
    csv.write_text("u,y\n" + rows + "\n", encoding="utf-8")
    named = ["--data", str(csv), "--inputs", "u", "--outputs", "y", "--dt", "0.5"]
    assert main(["evaluate", str(run), *named]) == 0


def test_analyze_data_that_do_not_exist_are_refused_not_ignored(root, tmp_path, capsys):
    out = tmp_path / "analysis"
    argv = [
        "analyze",
        "--run",
        str(root / "run"),
        "--budget",
        "1",
        "--no-progress",
        "--out",
        str(out),
    ]
    _refused(capsys, [*argv, "--data", str(tmp_path / "nonexistent.npz")], "nonexistent")
    assert not out.exists()


def test_analyze_refuses_a_run_of_another_system_by_its_sampling_time(root, tmp_path, capsys):
    """dt decides (the names differ too, but a CSV's column names are the user's labels and
    only warn)."""
    out = tmp_path / "analysis"
    argv = ["analyze", "linear", "--run", str(root / "run"), "--window", "3", "--trials", "2"]
    err = _refused(
        capsys, [*argv, "--budget", "1", "--no-progress", "--out", str(out)], "not trained on data"
    )
    assert "sampling time dt 0.5 (the run) vs 1.0 (linear)" in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--W", ""], "--W"),
        (["--X", ""], "--X"),
        (["--tol", "inf"], "--tol"),
        (["--tol", "nan"], "--tol"),
        (["--budget", "inf"], "--budget"),
        (["--budget", "nan"], "--budget"),
        (["--budget", "0"], "--budget"),
    ],
)
def test_analyze_refuses_empty_sets_and_non_finite_numbers(argv, needle, tmp_path, capsys):
    out = tmp_path / "analysis"
    base = ["analyze", "tank", "--window", "1", "--trials", "2", "--boxes", "2", "--no-progress"]
    _refused(capsys, [*base, *argv, "--out", str(out)], needle)
    assert not out.exists()


def test_export_into_a_path_below_a_file_says_so(root, tmp_path, capsys):
    blocker = tmp_path / "afile"
    blocker.write_text("mine\n", encoding="utf-8")
    argv = ["export", str(root / "run"), "--casadi", str(blocker / "m.casadi")]
    _refused(capsys, argv, "afile is a file", "expected a folder")
    assert blocker.read_text(encoding="utf-8") == "mine\n"


# ------------------------------------------------------------------ the budget bounds every stage
def _chain(length: int) -> ca.Function:
    """``f(x, u)`` through ``length`` operations: a graph as long as a large network's."""
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    v = x
    for _ in range(length // 4):
        v = ca.tanh(0.5 * v + 0.1 * u)
    return ca.Function("chain", [x, u], [v])


class _Clock:
    """``time.perf_counter`` moving ``step`` seconds at every call: a slow machine, exactly."""

    def __init__(self, step: float) -> None:
        self.now, self.step = 0.0, step

    def __call__(self) -> float:
        self.now += self.step
        return self.now


def test_the_sampled_lower_bound_stops_at_its_budget(monkeypatch):
    fun = _chain(8)
    X, U = Box([-1.0, -1.0], [1.0, 1.0]), Box([-1.0], [1.0])
    full = lipschitz.lipschitz_lower(fun, X, U, budget=Budget(samples=500, starts=2))
    assert full.details["stop"] == "all samples and local searches done"
    assert full.details["points_evaluated"] == 500 + 8 and full.details["local_searches"] == 2
    monkeypatch.setattr(lipschitz.time, "perf_counter", _Clock(1.0))
    cut = lipschitz.lipschitz_lower(fun, X, U, budget=Budget(seconds=2.5, samples=500, starts=2))
    assert cut.details["stop"] == "time budget exhausted"
    assert cut.details["points_evaluated"] < 500 and cut.details["local_searches"] == 0
    assert 0 < cut.value <= full.value  # still a lower bound: of the points it evaluated


def test_the_interval_evaluator_stops_at_its_deadline():
    fun = _chain(20_000)
    with pytest.raises(OutOfTime):
        Enclosure(fun, wrt=0, deadline=time.perf_counter() - 1.0)


def test_a_certified_search_out_of_time_is_the_trivial_bound_saying_why():
    fun = _chain(20_000)
    X, U = Box([-1.0, -1.0], [1.0, 1.0]), Box([-1.0], [1.0])
    upper = lipschitz.lipschitz_upper(fun, X, U, budget=Budget(seconds=1e-9))
    assert upper.value == np.inf and upper.details["stop"] == "time budget exhausted"
    assert "time budget ran out" in upper.details["why"]


# ------------------------------------------------------------------ the worker pool on SIGTERM
def test_sigterm_closes_the_worker_pool_cleanly(tmp_path):
    script = textwrap.dedent(
        """
        import sys, time
        from canonid.runner import run_jobs

        def job(i):
            time.sleep(0.5 if i == 0 else 60)
            return i

        def started(position, value):
            print("started", flush=True)

        run_jobs(job, list(range(4)), workers=2, progress=False, on_result=started)
        """
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        assert proc.stdout.readline().strip() == "started"
        proc.terminate()
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode != 0
    assert "leaked semaphore" not in err and "resource_tracker" not in err, err


def test_a_malformed_scheduler_address_is_named_not_reported_as_a_timeout():
    from canonid.runner import RunnerError, run_jobs

    with pytest.raises(RunnerError, match="malformed"):
        run_jobs(abs, [1], scheduler="not an address", progress=False)


# ------------------------------------------------------------------ random hostile run folders
#: files of a run folder that a mutation may touch (some absent until a command writes them)
RUN_FILES = (
    "run.json",
    "config.json",
    "normalisation.json",
    "metrics.json",
    "weights.pt",
    "checkpoint.pt",
    "history.csv",
    "rollouts.png",
    "training_curve.png",
)
JSON_FILES = ("run.json", "config.json", "normalisation.json", "metrics.json")

_json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**40), max_value=2**40)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3)
    ),
    max_leaves=6,
)
_mutations = st.one_of(
    st.tuples(st.just("field"), st.sampled_from(JSON_FILES), st.integers(0, 40), _json_values),
    st.tuples(st.just("bytes"), st.sampled_from(RUN_FILES), st.binary(max_size=64)),
    st.tuples(st.just("truncate"), st.sampled_from(RUN_FILES), st.floats(0.0, 0.99)),
    st.tuples(st.just("symlink"), st.sampled_from(RUN_FILES)),
    st.tuples(st.just("delete"), st.sampled_from(RUN_FILES)),
)


def _field_paths(body, prefix=()):
    """Every key path of a JSON body (objects only), outermost first."""
    if isinstance(body, dict):
        for key, value in body.items():
            yield (*prefix, key)
            yield from _field_paths(value, (*prefix, key))


def _mutate(run: Path, outside: Path, mutation) -> None:
    kind, name, *rest = mutation
    path = run / name
    if kind == "field":
        if not path.is_file() or path.is_symlink():
            return
        try:
            body = json.loads(path.read_bytes())
        except ValueError:  # already replaced by bytes that are no JSON
            return
        paths = list(_field_paths(body))
        if not paths:
            return
        _set(body, paths[rest[0] % len(paths)], rest[1])
        path.write_text(json.dumps(body), encoding="utf-8")  # NaN written as JSON's NaN
    elif kind == "bytes":
        path.unlink(missing_ok=True)
        path.write_bytes(rest[0])
    elif kind == "truncate" and path.is_file() and not path.is_symlink():
        data = path.read_bytes()
        path.write_bytes(data[: int(len(data) * rest[0])])
    elif kind == "symlink":
        victim = outside / f"victim-{name}"
        if not victim.exists():
            victim.write_bytes(b"the victim's own bytes\n")
        path.unlink(missing_ok=True)
        path.symlink_to(victim)
    elif kind == "delete":
        path.unlink(missing_ok=True)


def _set(body, keys, value) -> None:
    for key in keys[:-1]:
        body = body[key]
    body[keys[-1]] = value


def _commands(run: Path) -> dict[str, list[str]]:
    return {
        "evaluate": ["evaluate", str(run)],
        "export": ["export", str(run), "--casadi", str(run / "export" / "m.casadi")],
        "analyze": [
            "analyze",
            "--run",
            str(run),
            "--budget",
            "0.5",
            "--boxes",
            "4",
            "--no-progress",
        ],
        "resume": ["train", "--resume", "--out", str(run), "--epochs", "2", "--no-progress"],
    }


@pytest.mark.slow
@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    mutations=st.lists(_mutations, min_size=1, max_size=3),
    command=st.sampled_from(["evaluate", "export", "analyze", "resume"]),
)
# found by hypothesis: the cubic test's record is read from the checkpoint before training
@example(mutations=[("bytes", "checkpoint.pt", b"")], command="resume")
@example(mutations=[("symlink", "checkpoint.pt")], command="resume")
def test_random_hostile_run_folders_never_give_a_traceback_or_write_outside(
    root, mutations, command, capsys
):
    with tempfile.TemporaryDirectory() as scratch_name:
        scratch = Path(scratch_name)
        run = Path(shutil.copytree(root / "run", scratch / "run"))
        outside = scratch / "outside"
        outside.mkdir()
        (outside / "neighbour.txt").write_text("untouched\n", encoding="utf-8")
        for mutation in mutations:
            _mutate(run, outside, mutation)
        before_outside, before_data = _snapshot(outside), _snapshot(root / "data")
        try:
            code = main(_commands(run)[command])
        except SystemExit as exc:  # argparse: a usage error
            code = exc.code
        err = capsys.readouterr().err
        event(f"{command} exit {code}")
        assert code in (0, 1, 2), err
        assert "Traceback" not in err, err
        if code != 0:
            assert len(err.strip().splitlines()) == 1, err
        assert _snapshot(outside) == before_outside
        assert _snapshot(root / "data") == before_data
        assert sorted(p.name for p in scratch.iterdir()) == ["outside", "run"]


@pytest.fixture(scope="module")
def evaluated(root, tmp_path_factory):
    """A copy of the run with one evaluation of its test split stored (``evaluations/*/``)."""
    run = Path(shutil.copytree(root / "run", tmp_path_factory.mktemp("evaluated") / "run"))
    assert main(["evaluate", str(run)]) == 0
    return run


@pytest.mark.slow
@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(index=st.integers(0, 200), value=_json_values)
def test_any_field_of_a_stored_evaluation_changed_is_printed_or_named_never_a_traceback(
    evaluated, index, value, capsys
):
    """``canonid evaluate`` asked again reads the stored ``metrics.json`` back: with any one field
    set to any JSON value it prints the scores (exit 0) or names the file (exit 1, one line), and
    writes nothing."""
    with tempfile.TemporaryDirectory() as scratch:
        run = Path(shutil.copytree(evaluated, Path(scratch) / "run"))
        (stored,) = (run / "evaluations").glob("*/metrics.json")
        body = json.loads(stored.read_text(encoding="utf-8"))
        paths = list(_field_paths(body))
        _set(body, paths[index % len(paths)], value)
        stored.write_text(json.dumps(body), encoding="utf-8")
        before = _snapshot(run)
        capsys.readouterr()
        code = main(["evaluate", str(run)])
        err = capsys.readouterr().err
        event(f"exit {code}")
        assert "Traceback" not in err, err
        if code == 0:
            assert not err.strip(), err
        else:
            assert code == 1 and len(err.strip().splitlines()) == 1, err
            assert str(stored.parent) in err, err  # the file, or its folder of other weights
        assert _snapshot(run) == before


# ------------------------------------------------------------------ links and recorded paths (54)
def _victim(folder: Path) -> Path:
    """A tree of someone else's files, with the names a run folder's writers use."""
    for name in ("rollouts.png", "weights.pt", "config.json", "learned_analysis.json", "notes"):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(f"the victim's {name}\n".encode())
    (folder / "inner").mkdir()
    (folder / "inner" / "metrics.json").write_text('{"theirs": 1}\n', encoding="utf-8")
    return folder


def _sums(folder: Path) -> dict[str, str]:
    """Every entry below ``folder`` without following links: its kind and bytes' checksum."""
    import hashlib

    sums = {}
    for p in sorted(folder.rglob("*")):
        key = str(p.relative_to(folder))
        if p.is_symlink():
            sums[key] = "link " + str(p.readlink())
        elif p.is_dir():
            sums[key] = "folder"
        else:
            sums[key] = hashlib.sha256(p.read_bytes()).hexdigest()
    return sums


@pytest.fixture(scope="module")
def evaluation_dir(root, tmp_path_factory) -> str:
    """The folder name ``canonid evaluate RUN`` gives the run's test split."""
    run = Path(shutil.copytree(root / "run", tmp_path_factory.mktemp("named") / "run"))
    assert main(["evaluate", str(run)]) == 0
    (folder,) = (run / "evaluations").iterdir()
    return folder.name


@pytest.mark.parametrize("where", ["evaluations", "evaluations/NAME"])
def test_evaluate_follows_no_link_to_a_folder(where, root, evaluation_dir, tmp_path, capsys):
    run, victim = _run(root, tmp_path), _victim(tmp_path / "victim")
    before = _sums(victim)
    link = run / where.replace("NAME", evaluation_dir)
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(victim, target_is_directory=True)
    _refused(capsys, ["evaluate", str(run)], "symbolic link", where.split("/")[0])
    assert _sums(victim) == before


def test_analyze_run_follows_no_link_at_its_analysis_folder(root, tmp_path, capsys):
    run, victim = _run(root, tmp_path), _victim(tmp_path / "victim")
    before = _sums(victim)
    (run / "analysis").symlink_to(victim, target_is_directory=True)
    argv = ["analyze", "--run", str(run), "--budget", "0.5", "--boxes", "4", "--no-progress"]
    _refused(capsys, argv, "analysis", "symbolic link")
    assert _sums(victim) == before


@pytest.mark.parametrize("where", ["search", "search/l3-c16", "members", ".horizon-20.staged"])
def test_train_resume_follows_no_link_to_a_folder(where, root, tmp_path, capsys):
    """The search's candidates train in ``RUN/search/<name>``: a link there (or at another
    folder a resumed run writes) is refused, and the folder it points to is left alone."""
    run, victim = _run(root, tmp_path), _victim(tmp_path / "victim")
    before = _sums(victim)
    (run / where).parent.mkdir(parents=True, exist_ok=True)
    if where.startswith("search"):  # a search killed before its choice: it resumes there
        (run / "checkpoint.pt").unlink()
    if (run / where).is_dir():
        shutil.rmtree(run / where)
    (run / where).symlink_to(victim, target_is_directory=True)
    code = main(["train", "--resume", "--out", str(run), "--no-progress"])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if where.startswith("search"):
        assert code == 1 and "symbolic link" in err, err
    assert code == 0 or "symbolic link" in err, err
    assert _sums(victim) == before


def _crafted_horizon_check(run: Path, victim: Path, folder, state: str) -> None:
    """A ``horizon-check.json`` keeping H = 5 from ``folder`` (``VICTIM``: the victim's absolute
    path; ``LINK``: ``horizon-5/link``, a link to the victim planted for it)."""
    (run / "horizon-5").mkdir(exist_ok=True)
    if not (run / "horizon-5" / "link").exists():
        (run / "horizon-5" / "link").symlink_to(victim, target_is_directory=True)
    folder = {"VICTIM": str(victim), "LINK": "horizon-5/link"}.get(folder, folder)
    entry = {"window": 3, "outside": 0, "tests": 1, "largest": 0.0, "best_val_loss": None}
    body = {
        "format": "canonid-horizon-check",
        "version": 2,
        "limit": 0,
        "chosen": 5,
        "state": state,
        "k": 5,
        "confidence": 0.99,
        "candidates": [
            {**entry, "horizon": 20, "folder": "."},
            {**entry, "horizon": 5, "folder": folder},
        ],
    }
    (run / "horizon-check.json").write_text(json.dumps(body), encoding="utf-8")


@pytest.mark.parametrize(
    "folder", ["VICTIM", "../outside", "horizon-5/../../outside", "LINK", "", 3, None]
)
def test_a_horizon_check_record_may_name_only_a_folder_inside_the_run(
    folder, root, tmp_path, capsys
):
    """``horizon-check.json`` names its candidates' folders relative to the run: an absolute
    path, one with ``..``, or one through a link is named, and nothing is copied or moved."""
    run, victim = _run(root, tmp_path), _victim(tmp_path / "outside")
    _crafted_horizon_check(run, victim, folder, "adopting")
    before, mine = _sums(victim), _sums(run)
    argv = ["train", "--resume", "--out", str(run), "--epochs", "2", "--no-progress"]
    _refused(capsys, argv, "horizon-check.json", "candidates[1].folder")
    assert _sums(victim) == before and _sums(run) == mine


def test_a_hard_link_at_the_lock_is_refused_and_its_file_left_whole(root, tmp_path, capsys):
    run, victim = _run(root, tmp_path), _victim(tmp_path / "victim")
    before = _sums(victim)
    (run / ".canonid.lock").unlink(missing_ok=True)
    (run / ".canonid.lock").hardlink_to(victim / "notes")
    argv = ["train", "--resume", "--out", str(run), "--epochs", "2", "--no-progress"]
    _refused(capsys, argv, ".canonid.lock", "hard link")
    _refused(capsys, ["evaluate", str(run)], ".canonid.lock", "hard link")
    assert _sums(victim) == before


@pytest.mark.parametrize("name", ["config.json", "weights.pt", "test-ledger.jsonl"])
def test_a_hard_link_to_a_file_elsewhere_is_neither_read_nor_written(name, root, tmp_path, capsys):
    run, victim = _run(root, tmp_path), _victim(tmp_path / "victim")
    (victim / name).write_bytes((run / name).read_bytes() if (run / name).exists() else b"")
    before = _sums(victim)
    (run / name).unlink(missing_ok=True)
    (run / name).hardlink_to(victim / name)
    _refused(capsys, ["evaluate", str(run)], name, "hard link")
    assert _sums(victim) == before


#: folders of a run that a command may write, read or copy: a link to the victim planted there
LINKED_FOLDERS = (
    "evaluations",
    "evaluations/NAME",
    "analysis",
    "search",
    "search/l3-c16",
    "search/l3",
    "members",
    "horizon-5",
    ".horizon-20.staged",
)
#: files of a run: a hard link to a copy in the victim's tree planted there
LINKED_FILES = (
    *JSON_FILES,
    *RUN_FILES[4:6],  # weights.pt, checkpoint.pt
    "search.json",
    ".canonid.lock",
    "test-ledger.jsonl",
    "evaluations/NAME/metrics.json",
    "search/l3-c16/weights.pt",
    "search/l3-c16/checkpoint.pt",
)
#: what a crafted horizon-check.json may name as a candidate's folder (VICTIM: its absolute path)
RECORDED_FOLDERS = ("VICTIM", "../victim", "horizon-5/../../victim", "horizon-5", "LINK", ".")

_planted = st.one_of(
    st.tuples(st.just("folder link"), st.sampled_from(LINKED_FOLDERS)),
    st.tuples(st.just("hard link"), st.sampled_from(LINKED_FILES)),
    st.tuples(
        st.just("record"),
        st.sampled_from(RECORDED_FOLDERS),
        st.sampled_from(["adopting", "decided"]),
    ),
)


def _plant(run: Path, victim: Path, name: str, hazard) -> None:
    kind, where, *rest = hazard
    if kind == "folder link":
        path = run / where.replace("NAME", name)
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.is_symlink() or path.is_file():
            path.unlink()
        elif path.is_dir():
            shutil.rmtree(path)
        path.symlink_to(victim, target_is_directory=True)
    elif kind == "hard link":
        path = run / where.replace("NAME", name)
        if path.is_symlink() or not path.parent.is_dir() or path.parent.is_symlink():
            return
        copy = victim / "linked" / where.replace("/", "_")
        copy.parent.mkdir(exist_ok=True)
        if not copy.exists():
            copy.write_bytes(path.read_bytes() if path.is_file() else b"")
        path.unlink(missing_ok=True)
        path.hardlink_to(copy)
    else:
        _crafted_horizon_check(run, victim, where, rest[0])


#: the commands, a resumed training (the slowest, it scores the run again) one in ten
_PLANTED_COMMANDS = st.sampled_from([*["evaluate", "export", "analyze"] * 3, "resume"])


@pytest.mark.slow
@settings(
    max_examples=500, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(hazards=st.lists(_planted, min_size=1, max_size=3), command=_PLANTED_COMMANDS)
def test_planted_links_and_recorded_paths_never_change_a_file_outside_the_run(
    evaluated, evaluation_dir, hazards, command, capsys
):
    """Links to folders, hard links to files and crafted paths in records, planted at random in
    a run folder: every command exits with a line or succeeds, and the victim's tree (which the
    links point to) keeps every checksum."""
    with tempfile.TemporaryDirectory() as scratch_name:
        scratch = Path(scratch_name)
        run = Path(shutil.copytree(evaluated, scratch / "run", symlinks=True))
        victim = _victim(scratch / "victim")
        for hazard in hazards:
            _plant(run, victim, evaluation_dir, hazard)
        before = _sums(victim)
        argv = {
            "evaluate": ["evaluate", str(run)],
            "export": ["export", str(run), "--casadi", str(run / "export" / "m.casadi")],
            "analyze": ["analyze", "--run", str(run), "--budget", "0.05", "--boxes", "1"],
            "resume": ["train", "--resume", "--out", str(run)],
        }[command]
        try:
            code = main([*argv, "--no-progress"] if command in ("analyze", "resume") else argv)
        except SystemExit as exc:
            code = exc.code
        err = capsys.readouterr().err
        event(f"{command} exit {code}")
        assert code in (0, 1), err
        assert "Traceback" not in err, err
        if code != 0:
            assert len(err.strip().splitlines()) == 1, err
        assert _sums(victim) == before
        assert sorted(p.name for p in scratch.iterdir()) == ["run", "victim"]


# ------------------------------------------------------------------ nothing of the user's lost (54)
def test_analyze_out_refuses_a_folder_of_the_users_own_files(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "analysis.json").write_text('{"mine": true}\n', encoding="utf-8")
    argv = ["analyze", "tank", "--window", "2", "--out", str(out), "--no-progress"]
    _refused(capsys, argv, str(out), "canonid did not write", "analysis.json")
    assert [p.name for p in out.iterdir()] == ["analysis.json"]
    assert (out / "analysis.json").read_text(encoding="utf-8") == '{"mine": true}\n'


def test_a_failed_evaluation_write_removes_only_what_it_wrote(
    root, evaluation_dir, tmp_path, capsys
):
    """``rollouts.png`` is a folder: the write fails, and the evaluation folder keeps what was
    there before (a user's note, that folder) while what this evaluation wrote goes."""
    run = _run(root, tmp_path)
    folder = run / "evaluations" / evaluation_dir
    (folder / "rollouts.png").mkdir(parents=True)
    (folder / "notes.txt").write_text("mine\n", encoding="utf-8")
    before = _sums(folder)
    _refused(capsys, ["evaluate", str(run)], "rollouts.png")
    assert _sums(folder) == before


def test_a_run_json_without_checksum_and_a_relative_data_path_is_refused(
    root, tmp_path, monkeypatch, capsys
):
    """Neither a checksum nor a recorded folder to resolve ``data`` against: the current
    folder would decide what is scored, so the command names the file and asks for --data."""
    run = _run(root, tmp_path)
    elsewhere = tmp_path / "elsewhere"
    _dataset(2, 9, dt=0.5, names=("pump", "level")).save(elsewhere / "data" / "dataset.npz")
    _edit_json(run / "run.json", lambda r: r.update(data="data/dataset.npz", data_sha256=None))
    monkeypatch.chdir(elsewhere)
    before = _snapshot(run)
    _refused(
        capsys, ["evaluate", str(run)], "run.json", "no checksum", "--data", "data/dataset.npz"
    )
    assert _snapshot(run) == before
    data = str(root / "data" / "dataset.npz")
    assert main(["evaluate", str(run), "--data", data]) == 0


# ------------------------------------------------------------------ records checked (54)
@pytest.mark.parametrize(
    ("edit", "needles"),
    [
        (lambda m: m.update(rmse=12345), ("content_sha256", "edited by hand")),
        (lambda m: m.update(rollout_mse=float("nan")), ("'rollout_mse'", "a number or null")),
        (lambda m: m["kstep_nrmse"].__setitem__(0, {}), ("'kstep_nrmse'",)),
        (lambda m: m["kstep_nrmse_per_output"][0].pop(), ("'kstep_nrmse_per_output'",)),
        (lambda m: m.pop("content_sha256"), ("content_sha256", "missing")),
    ],
)
def test_a_stored_evaluation_edited_by_hand_is_named_not_printed(
    edit, needles, evaluated, tmp_path, capsys
):
    """The stored evaluation holds a checksum of its own content: a score changed by hand
    (``rmse: 12345``) is named as an edit, a number of the wrong kind or shape by its field."""
    run = Path(shutil.copytree(evaluated, tmp_path / "run"))
    (stored,) = (run / "evaluations").glob("*/metrics.json")
    _edit_json(stored, edit)
    before = _snapshot(run)
    err = _refused(capsys, ["evaluate", str(run)], str(stored), *needles)
    assert "12345" not in capsys.readouterr().out + err
    assert _snapshot(run) == before


@pytest.mark.parametrize(
    ("file", "edit", "needles"),
    [
        ("run.json", lambda r: r.update(window=5), ("run.json", "'window'", "config.json")),
        ("run.json", lambda r: r.update(model="gru"), ("run.json", "'model'", "config.json")),
        ("config.json", lambda c: c.update(format_version=99), ("'format_version'", "99")),
    ],
)
def test_run_json_and_config_json_that_disagree_are_refused(
    file, edit, needles, root, tmp_path, capsys
):
    run = _run(root, tmp_path)
    _edit_json(run / file, edit)
    before = _snapshot(run)
    _refused(capsys, ["evaluate", str(run)], *needles)
    _refused(capsys, ["export", str(run), "--casadi", str(tmp_path / "m.casadi")], *needles)
    assert _snapshot(run) == before and not (tmp_path / "m.casadi").exists()


# ------------------------------------------------------------------ messages (54)
@pytest.mark.parametrize(
    "command", [["evaluate"], ["reduce", "--compression", "0.5", "--no-progress"]]
)
def test_a_run_being_trained_names_its_writer_not_a_missing_model(command, tmp_path, capsys):
    """Before its first model is saved, a run folder holds its lock and ``run.json`` only: a
    reader is told who writes it and to wait, not that the folder "holds no model"."""
    from canonid.jobs import run_folder_lock

    run = tmp_path / "run"
    with run_folder_lock(run, new=True):
        (run / "run.json").write_text('{"format": "canonid-run"}\n', encoding="utf-8")
        err = _refused(capsys, [*command, str(run)], "being written by another canonid process")
    assert "holds no model yet" in err and f"pid {os.getpid()}" in err


def test_hidden_widths_for_arx_say_it_is_linear_not_the_gru_rule(root, tmp_path, capsys):
    argv = ["train", str(root / "data" / "dataset.npz"), "--model", "arx", "--hidden", "8"]
    err = _refused(capsys, [*argv, "--out", str(tmp_path / "run"), *COMMON], "--hidden", "arx")
    assert "linear" in err and "⌈ℓ" not in err
    assert not (tmp_path / "run").exists()


def test_constant_input_data_train_with_a_note_naming_the_column(tmp_path, caplog):
    """Issue 54: data whose input never changes trained without a word."""
    y = np.cumsum(np.random.default_rng(0).normal(size=160))
    csv = tmp_path / "flat.csv"
    csv.write_text("u,y\n" + "".join(f"1.5,{v:.17g}\n" for v in y), encoding="utf-8")
    argv = ["train", str(csv), "--inputs", "u", "--outputs", "y", "--dt", "1", "--window", "3"]
    with caplog.at_level("WARNING"):
        assert main([*argv, "--hidden", "8,8", "--out", str(tmp_path / "run"), *COMMON]) == 0
    notes = [r.getMessage() for r in caplog.records if "constant" in r.getMessage()]
    assert len(notes) == 1 and "'u'" in notes[0] and str(csv) in notes[0], notes


@pytest.mark.parametrize("where", ["members", "horizon-5"])
def test_a_run_folder_below_a_run_being_written_is_not_made_through_a_link(where, root, tmp_path):
    """A member's or a horizon alternative's run folder lies below the run: made and locked
    while the run's own lock is held, a link on its way is refused, its target left alone."""
    from canonid.jobs import run_folder_lock
    from canonid.kernel.errors import OutputError

    run, victim = _run(root, tmp_path), _victim(tmp_path / "victim")
    before = _sums(victim)
    (run / where).symlink_to(victim, target_is_directory=True)
    with run_folder_lock(run, flag="--out"), pytest.raises(OutputError, match="symbolic link"):
        with run_folder_lock(run / where / "s2", new=True):
            pass
    assert _sums(victim) == before
