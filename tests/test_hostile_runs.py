"""A run folder received from someone else is data (issue 29): ``evaluate``, ``export``,
``analyze --run`` and ``train --resume`` read it, and every bad field, mismatched dataset or
option gets one line naming it, a non-zero exit, and nothing written (outside the folder or
half-way). The analysis keeps to its ``--budget`` in every stage; the worker pool closes on
SIGTERM as on Ctrl-C.
"""

from __future__ import annotations

import json
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
    _refused(capsys, ["export", str(run), "--casadi", str(tmp_path / "m.casadi"), "--data", other])
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
