"""Input designs and the informativeness measure: spectra, seeds, clipping, a linear system whose
answer is known, and the paper's datasets unchanged."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest
from scipy.signal import lfilter

from canonid.datagen.excitation import Multisine, RandomBinary, design_from_options
from canonid.datagen.generate import GenerationConfig, generate_dataset
from canonid.datagen.informativeness import measure_informativeness
from canonid.kernel.dataset import Dataset
from canonid.kernel.errors import OptionError, ShapeError

# ---------------------------------------------------------------------------- signals


def test_multisine_has_its_rms_and_only_its_lines_inside_the_band():
    T, dt = 600, 1 / 30
    design = Multisine(band=(0.1, 5.0), lines=20, amplitude=(5.0, 2.0))
    d = design.signal(np.random.default_rng(0), T, dt, 2)
    assert d.shape == (T, 2)
    np.testing.assert_allclose(np.sqrt(np.mean(d**2, axis=0)), [5.0, 2.0], rtol=1e-9)
    spectra = np.abs(np.fft.rfft(d, axis=0))
    freqs = np.fft.rfftfreq(T, dt)
    for j in range(2):
        lines = np.flatnonzero(spectra[:, j] > 1e-6 * spectra[:, j].max())
        assert len(lines) == 20
        assert np.all((freqs[lines] >= 0.1 - 1e-9) & (freqs[lines] <= 5.0 + 1e-9))
    # interleaved: the two inputs share no frequency, so within a flight they are uncorrelated
    both = (spectra[:, 0] > 1e-6 * spectra[:, 0].max()) & (
        spectra[:, 1] > 1e-6 * spectra[:, 1].max()
    )
    assert not both.any()


def test_multisine_refuses_a_band_with_too_few_lines():
    with pytest.raises(OptionError, match=r"holds .* frequencies"):
        Multisine(band=(1.0, 1.2), lines=10, amplitude=1.0).signal(
            np.random.default_rng(0), 600, 1 / 30, 2
        )


def test_prbs_holds_each_level_for_its_clock():
    d = RandomBinary(clock=4, amplitude=3.0).signal(np.random.default_rng(1), 100, 0.1, 1)[:, 0]
    assert set(np.unique(d)) == {-3.0, 3.0}
    assert np.all(d.reshape(25, 4) == d[::4, None])


def test_design_options_refuse_what_does_not_belong():
    with pytest.raises(OptionError, match="--clock belongs to --excitation prbs"):
        design_from_options("multisine", amplitude=1.0, band=(0.1, 1.0), lines=2, clock=3)
    with pytest.raises(OptionError, match="needs --amplitude"):
        design_from_options("prbs", amplitude=None, clock=3)
    with pytest.raises(OptionError, match="amplitude must be one or more numbers > 0"):
        design_from_options("prbs", amplitude=-1.0, clock=3)


# ---------------------------------------------------------------------------- informativeness
# A linear SISO system of order n = 4 and the window ℓ = n: z_t has 2n = 8 entries and its
# covariance is of full rank exactly when u is persistently exciting of order ℓ + n = 8
# (Willems et al.'s fundamental lemma): white noise, or a multisine of >= 4 lines (each line is
# order 2). Otherwise the smallest eigenvalue is what the measurement noise adds, at most about
# σ_w² / σ_y² in standardised units. The first WARMUP samples are dropped so that the zero initial
# state's transient, which would add directions of its own, has died out (poles <= 0.7).
POLES, NUMERATOR = [0.7, -0.7, 0.5j, -0.5j], [0.0, 1.0, 1.0, 1.0, 1.0]
T, WARMUP, NOISE_STD = 2000, 200, 1e-3


def _linear_flight(u: np.ndarray, rng: np.random.Generator) -> tuple[tuple, float]:
    y = lfilter(NUMERATOR, np.real(np.poly(POLES)), u)[WARMUP:]
    floor = NOISE_STD**2 / np.var(y) if np.var(y) > 0 else 0.0
    noisy = y + NOISE_STD * np.sqrt(3) * rng.uniform(-1, 1, y.size)
    return (u[WARMUP:, None], noisy[:, None]), floor


def _periodic(design: Multisine, rng: np.random.Generator) -> np.ndarray:
    d = design.signal(rng, T, 1.0, 1)[:, 0]
    return np.concatenate([d[-WARMUP:], d])  # one period before: the loop is in steady state


@pytest.mark.parametrize("seed", [0, 1])
def test_persistently_exciting_inputs_give_a_full_rank_regressor_the_others_do_not(seed):
    rng = np.random.default_rng(seed)
    exciting = {
        "white noise": rng.standard_normal(T + WARMUP),
        "multisine, 4 lines": _periodic(Multisine((0.01, 0.45), 4, 1.0), rng),
    }
    not_exciting = {
        "multisine, 3 lines": _periodic(Multisine((0.01, 0.45), 3, 1.0), rng),
        "one sinusoid": np.sin(2 * np.pi * 0.05 * np.arange(T + WARMUP)),
        "constant": np.ones(T + WARMUP),
    }
    for name, u in exciting.items():
        flight, floor = _linear_flight(u, rng)
        measure = measure_informativeness([flight], window=4, dt=1.0)
        assert measure.smallest > 1e4 * floor, name
        assert measure.smallest > 1e-3, name
    for name, u in not_exciting.items():
        flight, floor = _linear_flight(u, rng)
        measure = measure_informativeness([flight], window=4, dt=1.0)
        assert measure.smallest < 10 * floor + 1e-12, name


def test_inputs_that_the_outputs_fix_leave_nothing_given_the_outputs():
    """Output feedback u = −0.5 y (plus nothing): the inputs are a function of the outputs."""
    rng = np.random.default_rng(0)
    y = np.cumsum(rng.standard_normal(500)) * 0.1
    closed = measure_informativeness([(-0.5 * y[:, None], y[:, None])], window=3, dt=1.0)
    opened = measure_informativeness(
        [(rng.standard_normal((500, 1)), y[:, None])], window=3, dt=1.0
    )
    assert closed.input_given_outputs < 1e-10
    assert opened.input_given_outputs > 0.5
    # what canonid generate prints: a covariance singular to rounding says so, not a bare 0
    from canonid.generation import informativeness_line

    assert "singular to rounding" in informativeness_line(closed)
    assert "singular to rounding" not in informativeness_line(opened)
    assert informativeness_line(opened).startswith("  informativeness (window 3): smallest")


def test_band_shares_put_a_slow_sine_in_the_lowest_octave():
    u = np.sin(2 * np.pi * 0.01 * np.arange(1000))[:, None]
    measure = measure_informativeness([(u, u)], window=2, dt=1.0, input_names=["a"])
    assert measure.band_shares["a"][0] == pytest.approx(1.0)
    assert sum(measure.band_shares["a"]) == pytest.approx(1.0)


# ---------------------------------------------------------------------------- generation
def _digest(folder) -> dict[str, str]:
    return {
        name: hashlib.sha256((folder / name).read_bytes()).hexdigest()
        for name in ("dataset.npz", "dataset.json")
    }


def test_the_paper_tank_dataset_has_the_bytes_main_wrote(tmp_path):
    """sha256 of ``canonid generate tank --n-train 2 --n-val 1 --n-test 1 --seed 0`` written by
    main at a9ad727, before input designs existed (the JSON records the package versions: the
    check holds for the versions the project pins)."""
    config = GenerationConfig(system="tank", seed=0, counts={"train": 2, "val": 1, "test": 1})
    generate_dataset(config, tmp_path)
    meta = json.loads((tmp_path / "dataset.json").read_text())
    assert "informativeness" not in meta["metadata"]
    digest = _digest(tmp_path)
    assert digest["dataset.npz"] == (
        "12847a1063a7f2f19fd203abdf1eb0d100660e822657e955d34ff5ca27f03ab2"
    )
    main_versions = {
        "canonid": "0.1.0",
        "casadi": "3.8.2",
        "numpy": "2.4.6",
        "python": "3.11.7",
        "scipy": "1.17.1",
    }
    if meta["metadata"]["versions"] == main_versions:  # the JSON names them: same versions only
        assert digest["dataset.json"] == (
            "49fbc5d42067a3e27d98285cd5014c93d24357d13de82a37a12173098c4a346c"
        )


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("drone2d-id")
    config = GenerationConfig(
        system="drone2d-id", seed=2, counts={"train": 2, "val": 0, "test": 1}, T=300
    )
    generate_dataset(config, folder)
    return config, folder


def test_designed_flights_record_the_input_as_applied_and_their_informativeness(designed):
    config, folder = designed
    dataset = Dataset.load(folder)
    system = config.true_system
    for flight in dataset.split("train"):
        assert np.all(flight.u >= system.U.lo) and np.all(flight.u <= system.U.hi)
        # the recorded input is the one the state saw: x[t+1] = f(x[t], u[t])
        for t in range(flight.T - 1):
            np.testing.assert_allclose(
                np.asarray(system.f(flight.x[t], flight.u[t])).ravel(), flight.x[t + 1], atol=1e-9
            )
    info = dataset.metadata["informativeness"]
    assert info["window"] == 10 and info["smallest_eigenvalue"] >= 0
    assert dataset.metadata["scenario"]["name"] == "drone2d-id"
    assert dataset.metadata["scenario"]["design"]["kind"] == "multisine"
    assert "child 2" in dataset.metadata["seeding"]


def test_designed_generation_is_the_same_on_workers(designed, tmp_path):
    from canonid.runner import run_jobs

    config, folder = designed
    generate_dataset(config, tmp_path, run_jobs=lambda *a, **k: run_jobs(*a, workers=2, **k))
    assert _digest(tmp_path) == _digest(folder)


def test_a_design_changes_the_inputs_and_nothing_drawn_before_it(tmp_path):
    """The design has its own child seed: the same flight without it has the same reference
    and noise."""
    counts = {"train": 1, "val": 0, "test": 0}
    plain = GenerationConfig(system="drone2d", seed=5, counts=counts, T=60)
    shaken = GenerationConfig(
        system="drone2d", seed=5, counts=counts, T=60, design=RandomBinary(clock=3, amplitude=4.0)
    )
    generate_dataset(plain, tmp_path / "plain")
    generate_dataset(shaken, tmp_path / "shaken")
    (a,), (b,) = (Dataset.load(tmp_path / k).split("train") for k in ("plain", "shaken"))
    np.testing.assert_array_equal(a.reference, b.reference)
    np.testing.assert_allclose(a.y - a.y_clean, b.y - b.y_clean, atol=1e-12)  # the same noise
    assert not np.allclose(a.u, b.u)
    assert Dataset.load(tmp_path / "shaken").metadata["generation"]["design"]["kind"] == "prbs"


def test_unknown_reference_family_is_refused():
    with pytest.raises(ShapeError, match="reference family 'zigzag' does not apply to drone2d"):
        GenerationConfig(system="drone2d", references="zigzag")


def test_generate_command_takes_a_design_and_prints_its_informativeness(tmp_path):
    from canonid.cli import main

    out = tmp_path / "d"
    argv = ["generate", "drone2d", "--n-train", "1", "--n-val", "0", "--n-test", "0"]
    argv += ["--steps", "90", "--excitation", "prbs", "--clock", "3", "--amplitude", "4,2"]
    assert main([*argv, "--out", str(out), "--no-progress"]) == 0
    design = Dataset.load(out).metadata["generation"]["design"]
    assert design == {**design, "kind": "prbs", "clock_samples": 3, "rms": [4.0, 2.0]}


def test_generate_command_refuses_design_options_without_excitation(tmp_path, capsys):
    from canonid.cli import main

    code = main(["generate", "drone2d", "--lines", "3", "--out", str(tmp_path / "d")])
    assert code != 0
    assert "--amplitude, --band, --lines and --clock need --excitation" in capsys.readouterr().err
    assert not (tmp_path / "d").exists()


# ---------------------------------------------------------------------------- the excitation, again
def test_the_drawn_excitation_is_the_one_a_flight_applied():
    """Under a feedforward command ``r``, the applied input is ``clip(r + (e + d), U)`` with the
    ``e`` that :func:`flight_draws` gives back from a generator of the same seed."""
    from canonid.datagen.controllers.feedforward import Feedforward
    from canonid.datagen.simulate import Excitation, flight_draws, simulate_closed_loop
    from canonid.models.registry import get_system

    system, T = get_system("tank"), 200
    rng = np.random.default_rng(4)
    reference = rng.uniform(1.0, 5.0, size=(T, 1))
    d = RandomBinary(clock=5, amplitude=0.5).signal(rng, T, system.dt, 1)
    excitation = Excitation(std=0.3)
    loop = simulate_closed_loop(
        system,
        Feedforward(1),
        reference,
        x0=np.array([1.0, 1.0]),
        rng=np.random.default_rng(9),
        excitation=excitation,
        clip_input=True,
        input_signal=d,
    )
    _, e, _, _ = flight_draws(
        np.random.default_rng(9), T, box=system.W, n_u=1, excitation=excitation
    )
    np.testing.assert_array_equal(loop.u, system.U.clip(reference + (e + d)))


def test_a_generated_flight_gives_back_its_design_signal(tmp_path):
    """The chain of masses is driven open loop by its multisine alone (zero reference, no
    Gaussian excitation): every unclipped input is the regenerated signal, to the bit."""
    from canonid.datagen.generate import dataset_excitation, flight_excitation

    config = GenerationConfig(
        system="masses-id", seed=3, counts={"train": 1, "val": 1, "test": 0}, T=1000
    )
    generate_dataset(config, tmp_path)
    data = Dataset.load(tmp_path)
    (flight,) = data.split("val")
    regenerated = flight_excitation(config, "val", 0)
    assert regenerated.design is not None and not regenerated.gaussian.any()
    free = np.all(np.abs(flight.u) < 20.0, axis=1)
    assert free.mean() > 0.9
    np.testing.assert_array_equal(flight.u[free], regenerated.total[free])
    (again,) = dataset_excitation(data, "val")
    np.testing.assert_array_equal(again.total, regenerated.total)


def test_a_configuration_reads_back_from_its_json():
    from canonid.datagen.generate import GenerationConfig as Config

    designed = Config(
        system="drone2d",
        seed=7,
        counts={"train": 3, "val": 1, "test": 0},
        noise=(0.01, 0.002, 0.005),
        T=90,
        design=Multisine(band=(0.1, 5.0), lines=4, amplitude=(2.0, 3.0)),
        references="steps",
    )
    for config in (designed, Config(system="drone2d-id"), Config(system="tank", noise=0.005)):
        assert Config.from_json(config.to_json()).to_json() == config.to_json()
    prbs = Config(system="tank", design=RandomBinary(clock=3, amplitude=0.5))
    assert Config.from_json(prbs.to_json()).design == prbs.design


def test_regenerating_the_excitation_refuses_data_from_elsewhere():
    from canonid.datagen.excitation import design_from_description
    from canonid.datagen.generate import dataset_excitation
    from canonid.kernel.errors import DataError

    data = Dataset.from_arrays(np.zeros((10, 1)), np.zeros((10, 1)), dt=0.1)
    with pytest.raises(DataError, match="only for datasets written by canonid generate"):
        dataset_excitation(data, "train")
    with pytest.raises(OptionError, match="design kind must be one of multisine, prbs"):
        design_from_description({"kind": "chirp"})
