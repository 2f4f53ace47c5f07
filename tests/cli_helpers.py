"""Assertions shared by the command-line tests."""

from __future__ import annotations


def one_line_error(capsys, code: int, *needles: str) -> str:
    """The command failed with exit 1 and one line on stderr, no traceback, holding every
    needle; returns that line."""
    err = capsys.readouterr().err
    assert code == 1, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err
