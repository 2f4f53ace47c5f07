"""The training horizon chosen by the input response (`canonid.horizon_check`), end to end as a
user types it: `canonid generate tank --excitation prbs` (PID in the loop, a PRBS added to its
commands) and `canonid train` on it. Where the decision itself is the subject, the check's counts
are set by the test (the real check's numbers are the residual check's, tested in
test_cli_residuals.py); the runs, the adoption of the alternative's files, `--resume` and an
interrupted adoption are real."""

from __future__ import annotations

import json
import math
import shutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import canonid.horizon_check as hc
from canonid.cli import main
from canonid.horizon_check import HORIZON_CHECK_FILE, HorizonCandidate, HorizonChoice

FAST = ["--profile", "tiny", "--epochs", "3", "--no-progress", "--device", "cpu", "--threads", "1"]
#: the alternative's rollouts in these tests: the tiny profile's own are 10
SHORT = 5
#: a ladder of two alternatives, tried in this order
MIDDLE = 7


@pytest.fixture(scope="module")
def closed_loop_data(tmp_path_factory):
    """A tank dataset flown by the PID with a PRBS on its commands (closed loop, excited)."""
    data = tmp_path_factory.mktemp("horizon") / "tank-prbs"
    argv = ["generate", "tank", "--n-train", "3", "--n-val", "2", "--n-test", "1", "--steps", "300"]
    argv += ["--excitation", "prbs", "--clock", "3", "--amplitude", "0.5", "--no-progress"]
    assert main([*argv, "--out", str(data)]) == 0
    return data


@pytest.fixture
def short_alternative(monkeypatch):
    monkeypatch.setattr(hc, "ALTERNATIVES", (SHORT,))


@pytest.fixture
def ladder(monkeypatch):
    monkeypatch.setattr(hc, "ALTERNATIVES", (MIDDLE, SHORT))


def _counts(monkeypatch, by_horizon):
    """The check's count of correlations outside the band, set per training horizon."""
    real = hc._checked

    def checked(run_dir, folder):
        found = real(run_dir, folder)
        return HorizonCandidate(**{**found.__dict__, "outside": by_horizon[found.horizon]})

    monkeypatch.setattr(hc, "_checked", checked)


def _bytes(path):
    return path.read_bytes()


def _recorded_horizon(run):
    return json.loads((run / "run.json").read_text())["train_options"]["horizon"]


@given(tests=st.integers(1, 400), confidence=st.sampled_from([0.9, 0.95, 0.99]))
@settings(max_examples=60, deadline=None)
def test_the_chance_limit_is_the_binomial_quantile(tests, confidence):
    """The smallest count whose binomial CDF under the null reaches the band's confidence."""

    def cdf(c):
        p = 1.0 - confidence
        return sum(math.comb(tests, j) * p**j * (1 - p) ** (tests - j) for j in range(c + 1))

    limit = hc.chance_limit(tests, confidence)
    assert cdf(limit) >= confidence - 1e-12
    assert limit == 0 or cdf(limit - 1) < confidence


def test_chance_allows_three_of_sixty_at_99_percent():
    """The drone's check at k = 10: 2 rotors × 3 outputs × 10 lags."""
    assert hc.chance_limit(60, 0.99) == 3


def test_the_check_runs_on_closed_loop_data_and_records_its_choice(
    closed_loop_data, short_alternative, tmp_path, capsys
):
    """The real check: the run's own count against the band and the chance limit decide whether
    the alternative trains; the one kept has the fewer correlations outside the band."""
    run = tmp_path / "run"
    assert main(["train", str(closed_loop_data), "--window", "3", *FAST, "--out", str(run)]) == 0
    choice = HorizonChoice.read(run)
    own = choice.own
    assert (own.horizon, own.window, own.tests) == (10, 3, 10)  # 1 input × 1 output × 10 lags
    assert choice.limit == hc.chance_limit(10, 0.99) and choice.state == "decided"
    if own.outside <= choice.limit:
        assert len(choice.candidates) == 1 and not choice.adopted
    else:
        other = choice.candidates[1]
        assert other.horizon == SHORT
        assert choice.adopted == (other.outside < own.outside)
    assert _recorded_horizon(run) == choice.chosen
    assert "input response (k = 10-step residuals against the excitation" in capsys.readouterr().out


def test_a_horizon_given_is_trained_as_given(closed_loop_data, short_alternative, tmp_path):
    run = tmp_path / "run"
    argv = ["train", str(closed_loop_data), "--window", "3", "--train-horizon", "20", *FAST]
    assert main([*argv, "--out", str(run)]) == 0
    assert not (run / HORIZON_CHECK_FILE).exists() and _recorded_horizon(run) == 20


def test_a_horizon_given_equal_to_the_profiles_stays_given_on_resume(
    closed_loop_data, short_alternative, tmp_path
):
    """`--train-horizon 10` is the tiny profile's own value: the recipe records that the user set
    it, so the run continued by --resume (without the option) is not checked either."""
    run = tmp_path / "run"
    argv = ["train", str(closed_loop_data), "--window", "3", "--train-horizon", "10", *FAST]
    assert main([*argv, "--out", str(run)]) == 0
    recipe = json.loads((run / "run.json").read_text())
    assert "horizon" in recipe["given_options"] and "seed" not in recipe["given_options"]
    resume = ["train", "--resume", "--out", str(run), "--epochs", "5", "--no-progress"]
    assert main([*resume, "--threads", "1"]) == 0
    assert not (run / HORIZON_CHECK_FILE).exists()
    assert json.loads((run / "run.json").read_text())["train_options"]["epochs"] == 5


def test_open_loop_data_and_arx_are_not_checked(closed_loop_data, tmp_path):
    """No feedback, no reading of the state from the inputs: a feedforward dataset is left as
    it is; ARX has no rollouts to shorten."""
    data = tmp_path / "chain"
    argv = ["generate", "masses-id", "--n-train", "1", "--n-val", "1", "--n-test", "1"]
    assert main([*argv, "--steps", "1000", "--no-progress", "--out", str(data)]) == 0
    run = tmp_path / "open"
    assert main(["train", str(data), "--window", "3", *FAST, "--out", str(run)]) == 0
    assert not (run / HORIZON_CHECK_FILE).exists()
    arx = tmp_path / "arx"
    argv = ["train", str(closed_loop_data), "--model", "arx", "--window", "3", *FAST]
    assert main([*argv, "--out", str(arx)]) == 0
    assert not (arx / HORIZON_CHECK_FILE).exists()


def test_an_alternative_with_fewer_correlations_becomes_the_run(
    closed_loop_data, short_alternative, monkeypatch, tmp_path, capsys
):
    """Flagged (20 of 10 is more than chance allows), the alternative validates its input
    response (0): its files become the run's, the run's own are kept in RUN/horizon-10, the
    choice is printed and recorded, and the run is read as the alternative by evaluate."""
    _counts(monkeypatch, {10: 8, SHORT: 0})
    run = tmp_path / "run"
    argv = ["train", str(closed_loop_data), "--window", "3", "--members", "1", *FAST]
    assert main([*argv, "--out", str(run)]) == 0
    out = capsys.readouterr().out
    assert "more than the 1 chance allows" in out and "H = 5 kept (its files in horizon-5" in out
    assert not (run / "members").exists()  # --members 1: the alternative alone
    choice = HorizonChoice.read(run)
    assert choice.adopted and choice.chosen == SHORT
    assert [c.outside for c in choice.candidates] == [8, 0]
    config = json.loads((run / "config.json").read_text())  # the adopted model's record
    assert choice.candidates[1].best_val_loss == config["info"]["training"]["best_val_loss"]
    assert _bytes(run / "weights.pt") == _bytes(run / "horizon-5" / "weights.pt")
    assert _bytes(run / "checkpoint.pt") == _bytes(run / "horizon-5" / "checkpoint.pt")
    assert _recorded_horizon(run) == SHORT and _recorded_horizon(run / "horizon-10") == 10
    assert _bytes(run / "weights.pt") != _bytes(run / "horizon-10" / "weights.pt")
    assert main(["evaluate", str(run)]) == 0


def test_an_alternative_that_does_no_better_is_not_kept(
    closed_loop_data, short_alternative, monkeypatch, tmp_path
):
    _counts(monkeypatch, {10: 8, SHORT: 8})  # a tie keeps the run's own
    run = tmp_path / "run"
    assert main(["train", str(closed_loop_data), "--window", "3", *FAST, "--out", str(run)]) == 0
    choice = HorizonChoice.read(run)
    assert not choice.adopted and _recorded_horizon(run) == 10
    assert (run / "horizon-5" / "weights.pt").is_file() and not (run / "horizon-10").exists()
    assert not (run / "members").exists()  # members by default only behind an adoption


def test_an_adopted_alternative_trains_members_held_to_its_input_response(
    closed_loop_data, short_alternative, monkeypatch, tmp_path, capsys
):
    """Behind an adoption the defaults train hc.MEMBERS members of the kept recipe; every
    candidate is checked as the run's model was, and the one kept has at most the run's own
    member's count of correlations outside the band."""
    from canonid.learning import Model
    from canonid.members import MEMBERS_FILE, MemberChoice

    _counts(monkeypatch, {10: 8, SHORT: 0})
    run = tmp_path / "run"
    assert main(["train", str(closed_loop_data), "--window", "3", *FAST, "--out", str(run)]) == 0
    body = json.loads((run / MEMBERS_FILE).read_text())
    assert body["count"] == hc.MEMBERS and "excitation" in body["criterion"]
    choice = MemberChoice.read(run)
    assert choice.outside is not None and choice.mean_outside is not None
    counts = dict(zip([f"seed {s}" for s in choice.seeds], choice.outside))
    counts.update({f"mean of {j}": n for (j, _), n in zip(choice.means, choice.mean_outside)})
    assert counts[choice.kept] <= choice.outside[0]
    own = run if choice.kept == "seed 0" else run / "members" / "s0"
    assert hc.response_count(run)(Model.load(own)) == choice.outside[0]  # the check's own count
    members = sorted((run / "members").glob("s[12]"))
    assert len(members) == hc.MEMBERS - 1 and all(_recorded_horizon(m) == SHORT for m in members)
    assert "correlations with the excitation outside the band" in capsys.readouterr().out


def test_resume_reads_the_choice_and_decides_nothing_again(
    closed_loop_data, short_alternative, monkeypatch, tmp_path
):
    _counts(monkeypatch, {10: 8, SHORT: 0})
    run = tmp_path / "run"
    assert main(["train", str(closed_loop_data), "--window", "3", *FAST, "--out", str(run)]) == 0
    weights = _bytes(run / "weights.pt")

    def no_more(*args, **kwargs):
        raise AssertionError("the recorded choice was made again")

    monkeypatch.setattr(hc, "_checked", no_more)
    assert main(["train", "--resume", "--out", str(run), "--no-progress"]) == 0
    assert _bytes(run / "weights.pt") == weights and HorizonChoice.read(run).adopted


def test_an_interrupted_adoption_is_finished_by_resume(
    closed_loop_data, short_alternative, monkeypatch, tmp_path
):
    """Killed while the alternative's files were being copied in: the record says so, and
    --resume copies the rest before it reads the run folder."""
    _counts(monkeypatch, {10: 8, SHORT: 0})
    run = tmp_path / "run"
    assert main(["train", str(closed_loop_data), "--window", "3", *FAST, "--out", str(run)]) == 0
    adopted = _bytes(run / "weights.pt")
    choice = HorizonChoice.read(run)
    # as an interruption leaves it: the record written first, some of the run's own files back
    HorizonChoice(choice.candidates, choice.limit, choice.chosen, "adopting").write(run)
    for name in ("run.json", "weights.pt"):
        shutil.copy(run / "horizon-10" / name, run / name)
    assert main(["train", "--resume", "--out", str(run), "--no-progress"]) == 0
    assert _bytes(run / "weights.pt") == adopted and HorizonChoice.read(run).state == "decided"
    assert _recorded_horizon(run) == SHORT


def test_an_interrupted_alternative_continues_to_the_same_bytes(
    closed_loop_data, short_alternative, monkeypatch, tmp_path
):
    """Stopped after the alternative trained, before the choice: --resume checks again, continues
    the alternative from its checkpoint and keeps the model an uninterrupted run keeps."""
    _counts(monkeypatch, {10: 8, SHORT: 0})
    whole = tmp_path / "whole"
    argv = ["train", str(closed_loop_data), "--window", "3", *FAST]
    assert main([*argv, "--out", str(whole)]) == 0

    run = tmp_path / "run"
    real = hc._checked

    def stop_at_the_alternative(run_dir, folder):
        if folder != ".":
            raise KeyboardInterrupt
        return real(run_dir, folder)

    monkeypatch.setattr(hc, "_checked", stop_at_the_alternative)
    assert main([*argv, "--out", str(run)]) != 0  # "canonid train: interrupted"
    assert not (run / HORIZON_CHECK_FILE).exists() and (run / "horizon-5" / "weights.pt").is_file()
    monkeypatch.setattr(hc, "_checked", real)  # the counts of the whole run again
    assert main(["train", "--resume", "--out", str(run), "--no-progress"]) == 0
    assert _bytes(run / "weights.pt") == _bytes(whole / "weights.pt")
    assert HorizonChoice.read(run).adopted


def test_the_alternative_trains_the_model_the_search_chose(
    closed_loop_data, short_alternative, monkeypatch, tmp_path
):
    """The run searched its window; the alternative trains the chosen window and branch with
    its shorter rollouts (nothing searched again), and once adopted the run's own searched
    files are kept aside in horizon-10."""
    _counts(monkeypatch, {10: 8, SHORT: 0})
    run = tmp_path / "run"
    assert main(["train", str(closed_loop_data), *FAST, "--out", str(run)]) == 0
    recipe = json.loads((run / "run.json").read_text())
    for alternative in ("horizon-10", "horizon-5"):
        theirs = json.loads((run / alternative / "run.json").read_text())
        assert theirs["window"] == recipe["window"]
        assert theirs["net_options"]["cubic"] == recipe["net_options"]["cubic"]
    assert (run / "horizon-10" / "search.json").is_file()
    assert not (run / "horizon-5" / "search.json").exists()


@pytest.mark.parametrize("progress", [True, False])
def test_records_too_short_for_the_check_leave_the_run_as_trained(
    progress, closed_loop_data, short_alternative, monkeypatch, tmp_path, capsys
):
    """The check needs ℓ + 2k + its filter's order samples per record; where the validation
    flights are shorter the run keeps its model, says so (once, with progress bars on or off:
    issue 54), and records no choice."""
    from canonid.kernel.errors import DataError

    def too_short(run_dir, folder):
        raise DataError("records of at most 30 samples; the check at k = 10 needs 33")

    monkeypatch.setattr(hc, "_checked", too_short)
    run = tmp_path / "run"
    shown = [option for option in FAST if option != "--no-progress" or not progress]
    argv = ["train", str(closed_loop_data), "--window", "3", *shown]
    assert main([*argv, "--out", str(run)]) == 0
    said = capsys.readouterr()
    assert (said.out + said.err).count("input response not checked: records of at most 30") == 1
    assert not (run / HORIZON_CHECK_FILE).exists() and _recorded_horizon(run) == 10


def test_members_follow_the_kept_horizon(
    closed_loop_data, short_alternative, monkeypatch, tmp_path
):
    """--members K trains the kept model's recipe from the next seeds: the alternative's rollouts
    once the check adopted it."""
    _counts(monkeypatch, {10: 8, SHORT: 0})
    run = tmp_path / "run"
    argv = ["train", str(closed_loop_data), "--window", "3", "--members", "2", *FAST]
    assert main([*argv, "--out", str(run)]) == 0
    assert HorizonChoice.read(run).adopted
    members = sorted((run / "members").glob("s*"))
    assert members and all(_recorded_horizon(m) == SHORT for m in members)


def test_members_not_given_are_not_recorded_and_the_default_decides(
    closed_loop_data, short_alternative, monkeypatch, tmp_path
):
    """Without --members the recipe records none (runs as before), and the members behind an
    adoption are the default's."""
    _counts(monkeypatch, {10: 8, SHORT: 0})
    run = tmp_path / "run"
    assert main(["train", str(closed_loop_data), "--window", "3", *FAST, "--out", str(run)]) == 0
    assert "members" not in json.loads((run / "run.json").read_text())
    assert len(list((run / "members").glob("s[12]"))) == hc.MEMBERS - 1
    members = json.loads((run / "members" / "s1" / "run.json").read_text())
    assert "members" not in members  # a member trains no members of its own


def test_the_ladder_stops_at_the_first_alternative_chance_allows(
    closed_loop_data, ladder, monkeypatch, tmp_path
):
    """Flagged at 10, the run tries 7 first; its count within what chance allows (1 of 10 here)
    ends the ladder: 5 is never trained, and 7 becomes the run."""
    _counts(monkeypatch, {10: 8, MIDDLE: 1, SHORT: 0})
    run = tmp_path / "run"
    argv = ["train", str(closed_loop_data), "--window", "3", "--members", "1", *FAST]
    assert main([*argv, "--out", str(run)]) == 0
    choice = HorizonChoice.read(run)
    assert [c.horizon for c in choice.candidates] == [10, MIDDLE] and choice.chosen == MIDDLE
    assert not (run / "horizon-5").exists() and _recorded_horizon(run) == MIDDLE
    assert _bytes(run / "weights.pt") == _bytes(run / "horizon-7" / "weights.pt")
    assert _recorded_horizon(run / "horizon-10") == 10


@pytest.mark.parametrize(
    ("counts", "chosen"),
    [
        ({10: 8, MIDDLE: 4, SHORT: 2}, SHORT),  # every rung flagged: the fewest
        ({10: 8, MIDDLE: 4, SHORT: 6}, MIDDLE),  # the shortest is worse than the middle one
        ({10: 8, MIDDLE: 8, SHORT: 8}, 10),  # a tie keeps the longer rollouts: the run's own
    ],
)
def test_where_every_rung_is_flagged_the_fewest_is_kept(
    closed_loop_data, ladder, monkeypatch, tmp_path, counts, chosen
):
    _counts(monkeypatch, counts)
    run = tmp_path / "run"
    argv = ["train", str(closed_loop_data), "--window", "3", "--members", "1", *FAST]
    assert main([*argv, "--out", str(run)]) == 0
    choice = HorizonChoice.read(run)
    assert [c.horizon for c in choice.candidates] == [10, MIDDLE, SHORT]
    assert [c.outside for c in choice.candidates] == [counts[h] for h in (10, MIDDLE, SHORT)]
    assert choice.chosen == chosen == _recorded_horizon(run)
    for horizon in (10, MIDDLE, SHORT):  # every model stays where it can be read
        folder = run if horizon == chosen else run / f"horizon-{horizon}"
        assert _recorded_horizon(folder) == horizon
    if chosen != 10:
        assert _bytes(run / "weights.pt") == _bytes(run / f"horizon-{chosen}" / "weights.pt")


def test_a_ladder_interrupted_between_its_rungs_continues_to_the_same_bytes(
    closed_loop_data, ladder, monkeypatch, tmp_path
):
    """Stopped after the first alternative trained, while the second trains: --resume checks
    the run and the first again, continues the second and keeps what an uninterrupted run
    keeps."""
    _counts(monkeypatch, {10: 8, MIDDLE: 4, SHORT: 2})
    argv = ["train", str(closed_loop_data), "--window", "3", "--members", "1", *FAST]
    whole = tmp_path / "whole"
    assert main([*argv, "--out", str(whole)]) == 0

    run = tmp_path / "run"
    counted = hc._checked

    def stop_at_the_second(run_dir, folder):
        if folder == "horizon-5":
            raise KeyboardInterrupt
        return counted(run_dir, folder)

    monkeypatch.setattr(hc, "_checked", stop_at_the_second)
    assert main([*argv, "--out", str(run)]) != 0
    assert not (run / HORIZON_CHECK_FILE).exists() and (run / "horizon-5" / "weights.pt").is_file()
    monkeypatch.setattr(hc, "_checked", counted)
    # --members 1 is not given again: run.json kept it, so no members train behind the adoption
    assert json.loads((run / "run.json").read_text())["members"] == 1
    assert main(["train", "--resume", "--out", str(run), "--no-progress"]) == 0
    assert not (run / "members").exists()
    assert HorizonChoice.read(run).chosen == SHORT
    assert _bytes(run / "weights.pt") == _bytes(whole / "weights.pt")


def test_a_recorded_check_of_an_earlier_canonid_reads_as_its_choice(tmp_path):
    """horizon-check.json version 1 (one alternative) reads as before: the ladder only adds
    candidates."""
    own = HorizonCandidate(50, ".", 20, 20, 60, 3.1, 0.19)
    other = HorizonCandidate(10, "horizon-10", 40, 6, 60, 1.8, 0.31)
    body = HorizonChoice((own, other), 3, 10).to_dict() | {"version": 1}
    (tmp_path / HORIZON_CHECK_FILE).write_text(json.dumps(body))
    choice = HorizonChoice.read(tmp_path)
    assert choice.adopted and choice.kept == other and choice.own == own
    assert "H = 10 kept (its files in horizon-10" in choice.summary()
