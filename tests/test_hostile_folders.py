"""A folder received from someone else is data, never a weapon (issue 29).

Each test builds its hostile folder itself: symlinks planted where canonid writes, planted
temporary names, a compiled-solver cache that others can write (with a valid checksum), a
``config.json`` whose architecture the weights do not hold. Each asserts that no victim file
changed, nothing planted ran or was loaded, and a refusal is one line naming the file and field.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import stat
import subprocess
from pathlib import Path

import pytest
import torch
from learning_helpers import damped_siso, trajectories
from matplotlib.figure import Figure

import canonid.datagen.controllers._compiled as compiled
from canonid.kernel.dataset import as_trajectories
from canonid.kernel.errors import CheckpointError, OutputError
from canonid.kernel.io import atomic_copy, atomic_copy_tree, atomic_write_figure
from canonid.learning import Model, Normalisation, build_net
from canonid.learning import model as model_module
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
    series = as_trajectories(data)
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


def test_atomic_copy_tree_replaces_the_folder_and_never_follows_a_planted_link(tmp_path):
    """The folder's old files are gone, the copy is whole, and a symlink planted at the folder's
    or at its staging name is replaced: the folder it points to keeps its files."""
    source = tmp_path / "alternative" / "cubic"
    (source / "inner").mkdir(parents=True)
    (source / "weights.pt").write_bytes(b"new weights")
    (source / "inner" / "history.csv").write_text("epoch\n1\n", encoding="utf-8")
    run = tmp_path / "run"
    (run / "cubic").mkdir(parents=True)
    (run / "cubic" / "stale.pt").write_bytes(b"old")
    assert atomic_copy_tree(source, run / "cubic") == run / "cubic"
    assert sorted(p.relative_to(run).as_posix() for p in (run / "cubic").rglob("*")) == [
        "cubic/inner",
        "cubic/inner/history.csv",
        "cubic/weights.pt",
    ]
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "theirs.txt").write_text(VICTIM_TEXT, encoding="utf-8")
    for name in ("planted", ".planted.staged"):
        (run / name).symlink_to(outside, target_is_directory=True)
    atomic_copy_tree(source, run / "planted")
    assert not (run / "planted").is_symlink() and (run / "planted" / "weights.pt").is_file()
    assert [p.name for p in outside.iterdir()] == ["theirs.txt"]
    assert (outside / "theirs.txt").read_text(encoding="utf-8") == VICTIM_TEXT
    assert not (run / ".planted.staged").exists()


def test_a_failed_atomic_copy_tree_leaves_the_old_folder(tmp_path):
    (tmp_path / "cubic").mkdir()
    (tmp_path / "cubic" / "weights.pt").write_bytes(b"old")
    with pytest.raises(OutputError, match=r"cannot copy .*missing to .*cubic"):
        atomic_copy_tree(tmp_path / "missing", tmp_path / "cubic")
    assert (tmp_path / "cubic" / "weights.pt").read_bytes() == b"old"


def test_the_search_adopts_the_chosen_model_without_a_fixed_temporary_name(tmp_path):
    from canonid.learning.model import MODEL_FILES
    from canonid.learning.search import adopt
    from canonid.learning.training import CHECKPOINT_FILE

    names = (CHECKPOINT_FILE, *MODEL_FILES)
    chosen = tmp_path / "search" / "l3"
    chosen.mkdir(parents=True)
    for name in names:
        (chosen / name).write_text(f"chosen {name}\n", encoding="utf-8")
    run = tmp_path / "run"
    victims = [_plant_symlink(run / f".{name}.tmp", tmp_path / "outside") for name in names]
    adopt(chosen, run)
    assert all(v.read_text(encoding="utf-8") == VICTIM_TEXT for v in victims)
    for name in names:
        assert not (run / name).is_symlink()
        assert (run / name).read_text(encoding="utf-8") == f"chosen {name}\n"


# ---------------------------------------------------------------------- crafted config.json
SAVED = {
    "mlp": {"hidden": [16, 16]},
    "gru": {"hidden_size": 8, "num_layers": 2, "head_hidden": [8]},
    "masti": {"hidden": [16], "latent_dim": 2},
}
LARGER = r" is larger than the \d+ numbers the weights in .*weights\.pt hold$"
ONLY = r"the weights in .*weights\.pt hold only {} tensors$"
CRAFTED = [  # (model, field, value, what the refusal says)
    ("mlp", "hidden", [400_000_000, 16], r"'net\.hidden\[0\]' = 400000000" + LARGER),
    ("mlp", "hidden", [50_000_000], r"'net\.hidden\[0\]' = 50000000" + LARGER),
    ("mlp", "hidden", [16] * 100_000, r"'net\.hidden' lists 100000 layers; " + ONLY.format(7)),
    (
        "mlp",
        "hidden",
        [17, 16],
        r"shape differs: net\.0\.bias \(16,\) in weights\.pt vs \(17,\) in",
    ),
    ("mlp", "hidden", [16], r"'net' \('mlp'.*do not fit: unexpected \['net\.4\.bias'"),
    ("mlp", "window", 4, r"'net' \('mlp', window 4.*do not fit: shape differs: net\.0\.weight"),
    ("mlp", "n_u", 10**12, r"'net\.n_u' = 1000000000000" + LARGER),
    ("gru", "num_layers", 10**9, r"'net\.num_layers' = 1000000000: " + ONLY.format(13)),
    ("gru", "hidden_size", 10**8, r"'net\.hidden_size' = 100000000" + LARGER),
    ("gru", "hidden_size", 9, r"'net' \('gru'.*do not fit: shape differs: "),
    ("masti", "latent_dim", 10**9, r"'net\.latent_dim' = 1000000000" + LARGER),
    ("mlp", "hidden", [-3, 16], r"'net' describes no network: .*negative dimension -3"),
    ("mlp", "hidden", [1e300, 16], r"'net' describes no network: model 'mlp': bad config"),
    ("mlp", "hidden", [4e8, 16], r"net\.0\.weight \(16, 7\) in weights\.pt vs \(400000000, 7\)"),
]


@pytest.fixture
def no_real_build(monkeypatch):
    """Fail the test if Model.load builds a network anywhere but on the meta device (where
    no memory is allocated) before it has refused the crafted configuration."""
    real = model_module.build_net

    def meta_only(name, **config):
        if torch.get_default_device().type != "meta":
            raise AssertionError(f"built {name!r} for real from an unchecked config {config}")
        return real(name, **config)

    monkeypatch.setattr(model_module, "build_net", meta_only)


@pytest.mark.parametrize(
    ("name", "field", "value", "says"),
    CRAFTED,
    ids=[f"{n}-{f}-{str(v)[:20]}" for n, f, v, _ in CRAFTED],
)
def test_a_crafted_config_is_refused_before_anything_is_built(
    name, field, value, says, siso_data, tmp_path, no_real_build
):
    torch.manual_seed(0)
    series = as_trajectories(siso_data)
    net = build_net(name, window=3, n_u=1, n_y=1, **SAVED[name])
    Model(net, Normalisation.fit(series)).save(tmp_path / "run")
    config_file = tmp_path / "run" / "config.json"
    config = json.loads(config_file.read_text(encoding="utf-8"))
    config["net"][field] = value
    config_file.write_text(json.dumps(config), encoding="utf-8")
    with pytest.raises(CheckpointError, match=says) as refused:
        Model.load(tmp_path / "run")
    message = str(refused.value)
    assert "\n" not in message and message.startswith(f"{config_file}: field 'net")


@pytest.mark.parametrize("model", [["mlp"], {"mlp": 1}, None, "rnn"])
def test_a_config_naming_no_model_is_one_line(model, siso_data, tmp_path):
    _small_mlp(siso_data).save(tmp_path / "run")
    config_file = tmp_path / "run" / "config.json"
    config = json.loads(config_file.read_text(encoding="utf-8"))
    config_file.write_text(json.dumps({**config, "model": model}), encoding="utf-8")
    with pytest.raises(CheckpointError, match=r"config\.json: field 'model' must be one of "):
        Model.load(tmp_path / "run")


def test_an_untouched_run_still_loads_after_the_check(siso_data, tmp_path):
    model = _small_mlp(siso_data)
    model.save(tmp_path / "run")
    loaded = Model.load(tmp_path / "run")
    tr = siso_data[0]
    assert loaded.net.config() == model.net.config()
    assert (loaded.simulate(tr.u, tr.y[:3]) == model.simulate(tr.u, tr.y[:3])).all()


# ---------------------------------------------------------------------- compiled-solver cache
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs a C compiler")
as_root = pytest.mark.skipif(os.geteuid() != 0, reason="giving a file to another user needs root")
OTHER_UID = 54321  # a user that is not this one (only root can give files away)


def _square():
    import casadi as ca

    x = ca.SX.sym("x")
    return ca.Function("square", [x], [x**2 + 1])


def _planted_cache(cache: Path, marker: Path) -> Path:
    """A cache whose library (found where canonid looks for it) is a planted one, with a
    matching checksum, whose constructor creates ``marker`` when it is loaded."""
    assert compiled.compile_functions([_square()], name="sq", cache_dir=cache) is not None
    (library,) = cache.glob("sq-*.so")
    source = cache.parent / "planted.c"
    source.write_text(
        "#include <stdio.h>\n"
        "__attribute__((constructor)) static void planted(void) {\n"
        f'    FILE *f = fopen("{marker}", "w");\n'
        "    if (f) fclose(f);\n"
        "}\n",
        encoding="utf-8",
    )
    planted = cache.parent / "planted.so"
    subprocess.run(["gcc", "-shared", "-fPIC", str(source), "-o", str(planted)], check=True)
    os.replace(planted, library)  # a new file: this process still maps the one it loaded
    compiled._checksum_file(library).write_text(compiled.sha256_file(library) + "\n")
    return library


def _one_warning(caplog) -> str:
    lines = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(lines) == 1 and "\n" not in lines[0], lines
    return lines[0]


UNTRUSTED_FOLDERS = {  # how the cache folder is made untrustworthy, what the refusal says
    "world-writable": (lambda cache: cache.chmod(0o777), r"{cache} is writable by others"),
    "group-writable": (lambda cache: cache.chmod(0o770), r"{cache} is writable by others"),
    "parent writable by others": (
        lambda cache: cache.parent.chmod(0o777),
        r"{parent} is writable by others",
    ),
    "owned by another user": (
        lambda cache: os.chown(cache, OTHER_UID, -1),
        r"{cache} is owned by uid 54321",
    ),
}


@needs_gcc
@pytest.mark.parametrize("how", list(UNTRUSTED_FOLDERS))
def test_a_cache_folder_others_can_write_is_not_used(how, tmp_path, caplog):
    if how == "owned by another user" and os.geteuid() != 0:
        pytest.skip("giving a folder to another user needs root")
    cache, marker = tmp_path / "shared" / "cache", tmp_path / "planted-library-ran"
    library = _planted_cache(cache, marker)
    planted = library.read_bytes()
    spoil, says = UNTRUSTED_FOLDERS[how]
    spoil(cache)
    caplog.clear()
    assert compiled.compile_functions([_square()], name="sq", cache_dir=cache) is None
    assert not marker.exists()
    assert library.read_bytes() == planted  # neither loaded nor rebuilt: nothing written there
    message = _one_warning(caplog)
    assert re.search(
        says.format(cache=re.escape(str(cache)), parent=re.escape(str(cache.parent))), message
    )
    assert "using the pure-CasADi solver" in message and "chmod go-w" in message


@needs_gcc
def test_a_sticky_parent_such_as_tmp_is_fine(tmp_path, caplog):
    (tmp_path / "tmp").mkdir(mode=0o1777)
    (tmp_path / "tmp").chmod(0o1777)
    built = compiled.compile_functions([_square()], name="sq", cache_dir=tmp_path / "tmp" / "c")
    assert built is not None and float(built[0](3.0)) == 10.0
    assert not [r for r in caplog.records if r.levelname == "WARNING"]


def _symlink_to_planted(library: Path) -> None:
    elsewhere = library.parent.parent / "elsewhere.so"
    os.replace(library, elsewhere)
    library.symlink_to(elsewhere)
    compiled._checksum_file(library).write_text(compiled.sha256_file(elsewhere) + "\n")


UNTRUSTED_FILES = {  # how a cached file is made untrustworthy, what the warning says
    "library world-writable": (lambda lib: lib.chmod(0o666), r"{lib} is writable by others"),
    "checksum group-writable": (
        lambda lib: compiled._checksum_file(lib).chmod(0o664),
        r"{lib}\.sha256 is writable by others",
    ),
    "library a symlink": (_symlink_to_planted, r"{lib} is a symbolic link"),
    "library owned by another user": (
        lambda lib: os.chown(lib, OTHER_UID, -1),
        r"{lib} is owned by uid 54321",
    ),
}


@needs_gcc
@pytest.mark.parametrize("how", list(UNTRUSTED_FILES))
def test_a_cached_file_others_could_have_written_is_rebuilt_not_loaded(how, tmp_path, caplog):
    if how == "library owned by another user" and os.geteuid() != 0:
        pytest.skip("giving a file to another user needs root")
    cache, marker = tmp_path / "cache", tmp_path / "planted-library-ran"
    library = _planted_cache(cache, marker)
    spoil, says = UNTRUSTED_FILES[how]
    spoil(library)
    caplog.clear()
    built = compiled.compile_functions([_square()], name="sq", cache_dir=cache)
    assert not marker.exists()
    assert built is not None and float(built[0](4.0)) == 17.0
    message = _one_warning(caplog)
    assert re.search(says.format(lib=re.escape(str(library))), message)
    assert "rebuilding it" in message
    for path in (library, compiled._checksum_file(library)):
        info = path.lstat()
        assert stat.S_ISREG(info.st_mode) and info.st_uid == os.geteuid()
        assert info.st_mode & 0o022 == 0


@needs_gcc
def test_a_new_cache_is_private_even_under_a_permissive_umask(tmp_path, caplog):
    old = os.umask(0o002)
    try:
        built = compiled.compile_functions([_square()], name="sq", cache_dir=tmp_path / "a" / "c")
    finally:
        os.umask(old)
    assert built is not None
    assert stat.S_IMODE((tmp_path / "a" / "c").stat().st_mode) == 0o700
    for path in (tmp_path / "a" / "c").iterdir():
        assert path.stat().st_mode & 0o022 == 0, path
    again = compiled.compile_functions([_square()], name="sq", cache_dir=tmp_path / "a" / "c")
    assert again is not None and not [r for r in caplog.records if r.levelname == "WARNING"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
