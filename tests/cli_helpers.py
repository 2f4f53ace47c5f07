"""Assertions shared by the command-line tests."""

from __future__ import annotations

import json
from pathlib import Path


def one_line_error(capsys, code: int, *needles: str) -> str:
    """The command failed with exit 1 and one line on stderr, no traceback, holding every
    needle; returns that line."""
    err = capsys.readouterr().err
    assert code == 1, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def evaluated(run: Path, out: str) -> dict:
    """The ``metrics.json`` of the evaluation that ``canonid evaluate`` just wrote into ``run``
    (named on the last line of its stdout ``out``), checked to lie in ``run/evaluations``."""
    last = out.strip().splitlines()[-1]
    if last.startswith("metrics written to "):
        folder = Path(last.removeprefix("metrics written to ")).parent
    else:
        assert last.startswith("already evaluated: "), out
        folder = Path(last.removeprefix("already evaluated: ").split(" (")[0])
    assert folder.parent == run / "evaluations", out
    return json.loads((folder / "metrics.json").read_text(encoding="utf-8"))
