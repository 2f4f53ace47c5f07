"""The public surface: ``import canonid`` and the command table, and what each loads."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import canonid
from canonid.cli import main
from canonid.commands import COMMANDS, command_names

ROOT = Path(__file__).resolve().parents[1]


def _loaded_after(code: str) -> set[str]:
    """The heavy packages (torch, CasADi, matplotlib) a fresh interpreter holds after ``code``."""
    probe = (
        f"{code}\n"
        "import sys\n"
        "print(' '.join(m for m in ('torch', 'casadi', 'matplotlib') if m in sys.modules))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr[-2000:]
    return set(res.stdout.split())


def _cli(*argv: str) -> str:
    """Run ``canonid argv`` in-process (output discarded), ending on ``--help``'s exit too."""
    return (
        "import contextlib, io\n"
        "from canonid.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        f"        main({list(argv)!r})\n"
        "    except SystemExit as exc:\n"
        "        assert exc.code == 0, exc.code\n"
    )


def test_import_canonid_loads_no_heavy_package():
    assert _loaded_after("import canonid") == set()


@pytest.mark.parametrize(
    ("argv", "allowed"),
    [
        (("--help",), set()),
        (("systems",), {"casadi"}),  # the registry defines the systems in CasADi
        (("generate", "--help"), {"casadi"}),
    ],
)
def test_fast_commands_do_not_load_torch(argv, allowed):
    assert _loaded_after(_cli(*argv)) <= allowed


def test_generate_runs_to_its_dataset_without_torch(tmp_path):
    out = tmp_path / "tank"
    argv = ("generate", "tank", "--out", str(out), "--n-train", "1", "--n-val", "0")
    assert "torch" not in _loaded_after(_cli(*argv, "--n-test", "0", "--no-progress"))
    assert (out / "dataset.npz").is_file()


@pytest.mark.parametrize("name", sorted(set(canonid.__all__) - {"__version__"}))
def test_public_names_are_the_library_objects_and_documented(name):
    home = importlib.import_module(canonid._EXPORTS[name])
    assert getattr(canonid, name) is getattr(home, name)
    assert f"`{name}`" in (canonid.__doc__ or ""), f"{name} is not in canonid's docstring"


def test_fit_defaults_to_the_options_canonid_train_uses(monkeypatch):
    # canonid.fit without options trains with the quick profile's train stage, as the CLI does
    from canonid.api import fit
    from canonid.learning import training
    from canonid.profiles import DEFAULT_PROFILE, train_options

    seen = {}
    monkeypatch.setattr(training, "fit", lambda *a, **kw: seen.update(kw))
    fit([], [], window=3, cubic=0)  # both axes fixed: one network, no search
    assert seen["options"] == train_options(DEFAULT_PROFILE)
    assert seen["options"] != training.TrainOptions()
    custom = train_options("tiny", epochs=2)
    fit([], [], window=3, cubic=0, options=custom, net_options={"hidden": [8]})
    assert seen["options"] is custom and seen["net_options"] == {"hidden": [8], "cubic": 0}


def test_fit_without_validation_data_names_the_argument():
    import numpy as np

    data = canonid.Dataset.from_arrays(np.ones((30, 1)), np.ones((30, 1)), dt=1.0)
    with pytest.raises(canonid.kernel.OptionError, match=r"^val: validation trajectories .*"):
        canonid.fit(data.split("train"), None, window=2, options=canonid.train_options("tiny"))


def test_public_names_are_listed_once():
    assert sorted(canonid.__all__) == sorted(["__version__", *canonid._EXPORTS])
    assert set(canonid.__all__) <= set(dir(canonid))
    with pytest.raises(AttributeError, match="no attribute 'fitt'"):
        _ = canonid.fitt


def test_dir_lists_only_the_public_names():
    names = {n for n in dir(canonid) if not n.startswith("__")}
    assert names >= set(canonid._EXPORTS)
    assert not names & {"TYPE_CHECKING", "annotations", "lazy_exports", "_EXPORTS"}
    modules = {n for n in names - set(canonid._EXPORTS) if not callable(getattr(canonid, n))}
    assert all(getattr(canonid, n).__name__ == f"canonid.{n}" for n in modules)  # subpackages


def test_fit_shows_every_setting_in_its_signature():
    """In the manner of python-control's kwargs_test: no ``**kwargs``, and every keyword of the
    library's trainer that a user sets is a keyword of ``canonid.fit`` too."""
    import inspect

    from canonid.learning import training

    ours = inspect.signature(canonid.fit).parameters
    assert not [p for p in ours.values() if p.kind is p.VAR_KEYWORD]
    library = set(inspect.signature(training.fit).parameters) - {"until"}  # the search's own
    assert library <= set(ours), library - set(ours)
    for name in ("model", "window", "cubic", "max_window", "options", "profile", "net_options"):
        assert ours[name].kind is ours[name].KEYWORD_ONLY, name
    doc = canonid.fit.__doc__ or ""
    assert all(f"``{name}``" in doc for name in ours if name not in ("train", "val")), doc


def test_scores_print_as_a_short_table():
    import numpy as np

    rng = np.random.default_rng(0)

    def record(length=60):
        u, y = rng.normal(size=(length, 1)), np.zeros((length, 2))
        for t in range(1, length):
            y[t] = 0.8 * y[t - 1] + 0.2 * u[t - 1]
        return canonid.Trajectory(u=u, y=y)

    data = [record() for _ in range(3)]
    tiny = canonid.train_options("tiny", epochs=1)
    result = canonid.fit(data[:2], data[2:], window=3, cubic=0, options=tiny)
    scores = canonid.evaluate(result.model, [record(), record()], horizon=10)
    table = str(scores).splitlines()
    assert len(table) == 5 and table[1].split() == [
        "target",
        "rollout_mse",
        "rmse",
        "nrmse",
        "fit",
        "%",
    ]
    assert table[2].startswith("y (measured)") and [r.split()[0] for r in table[3:]] == ["y1", "y2"]
    assert str(scores.measured).splitlines()[0] == table[1]
    for text in (repr(scores), repr(scores.measured)):
        assert "\n" not in text and len(text) < 200, text
    assert repr(scores).startswith("Evaluation(model='mlp', window=3, rollout_mse=")


def test_the_command_table_names_every_command_module():
    modules = {
        p.stem for p in (ROOT / "canonid" / "commands").glob("*.py") if not p.stem.startswith("_")
    }
    assert set(command_names()) == modules
    for command in COMMANDS:
        module = command.load()
        assert callable(module.register) and callable(module.run)


def test_help_lists_every_command_with_its_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps long lines
    for command in COMMANDS:
        assert f"{command.name} {command.help.replace('%%', '%')}" in out
