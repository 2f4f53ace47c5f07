"""`canonid evaluate --residuals` end to end, as a user types it: a tank dataset of `canonid
generate` with a PRBS design, an ARX run trained on it, the check against the regenerated
excitation; the same validation flights as a CSV file fall back to the inputs; a bad K, and a
--json file that exists, are one line on stderr."""

from __future__ import annotations

import json

import pytest
from cli_helpers import one_line_error

from canonid.cli import main
from canonid.kernel.dataset import Dataset

QUICK = ["--no-progress", "--device", "cpu"]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """``canonid generate tank --excitation prbs …`` and ``canonid train DATA --model arx``."""
    root = tmp_path_factory.mktemp("residuals")
    data, run = root / "tank-prbs", root / "arx"
    argv = ["generate", "tank", "--n-train", "2", "--n-val", "2", "--n-test", "1"]
    argv += ["--steps", "300", "--excitation", "prbs", "--clock", "3", "--amplitude", "0.5"]
    assert main([*argv, "--out", str(data), "--no-progress"]) == 0
    argv = ["train", str(data), "--model", "arx", "--window", "3", *QUICK, "--out", str(run)]
    assert main(argv) == 0
    return data, run


def _k_lines(out: str) -> dict[int, str]:
    """The printed line of each horizon, by k."""
    lines = [line for line in out.splitlines() if line.startswith("k = ")]
    return {int(line.split(":")[0].removeprefix("k = ")): line for line in lines}


def test_the_check_reads_the_regenerated_excitation_and_writes_nothing_to_the_run(trained, capsys):
    data, run = trained
    capsys.readouterr()
    before = sorted(p.name for p in run.iterdir())
    code = main(["evaluate", str(run), "--data", str(data), "--split", "val", "--residuals", "20"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "against the excitation e + d regenerated from the flights' seeds" in out
    assert "note:" not in out
    assert "[val], 2 records" in out and "rows t = 22 … T − 1" in out  # ℓ + 20 − 1
    lines = _k_lines(out)
    assert sorted(lines) == [1, 10, 20]
    assert lines[10].startswith("k = 10: ") and " / 10 outside the band" in lines[10]
    assert "per output y " in lines[20] and "/20" in lines[20]
    assert out.strip().splitlines()[-1].startswith("estimates: ")
    assert sorted(p.name for p in run.iterdir()) == before  # no evaluations folder


def test_without_split_the_check_reads_validation_not_test(trained, capsys):
    """With --data and with the run's own data (whose scores read test): validation."""
    data, run = trained
    capsys.readouterr()
    assert main(["evaluate", str(run), "--data", str(data), "--residuals"]) == 0
    assert "[val], 2 records" in capsys.readouterr().out  # the data have a test split too
    assert main(["evaluate", str(run), "--residuals"]) == 0
    assert "[val], 2 records" in capsys.readouterr().out
    assert main(["evaluate", str(run), "--residuals", "--split", "test"]) == 0
    assert "[test], 1 record" in capsys.readouterr().out  # asked for by name


def test_json_is_the_typed_result_and_is_not_overwritten(trained, tmp_path, capsys):
    _, run = trained
    target = tmp_path / "check.json"
    argv = ["evaluate", str(run), "--split", "val", "--residuals", "--json", str(target)]
    assert main(argv) == 0
    printed = _k_lines(capsys.readouterr().out)
    body = json.loads(target.read_text())
    assert body["kind"] == "estimate" and body["instrument"] == "excitation"
    assert sorted(body["tests"]) == ["1", "10"]  # --residuals alone: k = 1 and 10
    ten = body["tests"]["10"]
    assert ten["lags"] == list(range(1, 11)) and ten["null_lags"] == 10 + 3 - 1 + 10
    assert f"k = 10: {ten['outside']} / 10 outside" in printed[10]
    written = target.read_bytes()
    one_line_error(capsys, main(argv), "--json", str(target), "exists")
    assert target.read_bytes() == written


def test_csv_records_fall_back_to_the_inputs_and_say_so(trained, tmp_path, capsys):
    data, run = trained
    rows = ["run,time,u,y"]
    dataset = Dataset.load(data)
    for i, tr in enumerate(dataset.split("val")):
        rows += [
            f"r{i},{t * dataset.dt},{float(tr.u[t, 0])!r},{float(tr.y[t, 0])!r}"
            for t in range(tr.T)
        ]
    csv = tmp_path / "val.csv"
    csv.write_text("\n".join(rows) + "\n")
    argv = ["evaluate", str(run), "--data", str(csv), "--inputs", "u", "--outputs", "y"]
    capsys.readouterr()
    code = main([*argv, "--experiment-column", "run", "--residuals", "5"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "against the recorded inputs" in out and "[all], 2 records" in out
    notes = [line for line in out.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "can flag a correct model" in notes[0]
    assert "excitation you added" in notes[0]
    assert sorted(_k_lines(out)) == [1, 5, 10]


@pytest.mark.parametrize(
    ("extra", "needles"),
    [
        (["--residuals", "0"], ("--residuals K must be an integer >= 1", "0")),
        (["--residuals", "--stride", "5"], ("--stride", "takes none of them")),
        (["--json", "x.json"], ("--json FILE", "give --residuals")),
        (["--residuals", "400"], ("needs one of", "give a smaller K")),
    ],
)
def test_a_bad_argument_is_one_line(trained, extra, needles, capsys):
    _, run = trained
    capsys.readouterr()
    one_line_error(capsys, main(["evaluate", str(run), "--split", "val", *extra]), *needles)


def test_a_missing_data_file_is_one_line(trained, tmp_path, capsys):
    _, run = trained
    missing = tmp_path / "nowhere.csv"
    code = main(["evaluate", str(run), "--data", str(missing), "--residuals"])
    one_line_error(capsys, code, str(missing))
