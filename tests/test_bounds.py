"""Sizes and numbers a user can give that would make canonid allocate without bound, divide by
zero or fail deep inside numpy or torch (issue 54, cases 7, 8, 9, 12 and 22): each is refused in
one line that names the argument or file and what was expected, exit 1, before anything is
written."""

from __future__ import annotations

import math
from pathlib import Path

from cli_helpers import one_line_error

from canonid.cli import main

TINY = ["--profile", "tiny", "--epochs", "1", "--device", "cpu", "--no-progress"]
CSV = ["--inputs", "u", "--outputs", "y", "--dt", "1"]


def _csv(path: Path, y=lambda t: math.cos(0.2 * t), n: int = 120) -> Path:
    rows = "".join(f"{math.sin(0.3 * t)!r},{float(y(t))!r}\n" for t in range(n))
    path.write_text("u,y\n" + rows, encoding="utf-8")
    return path


def test_a_constant_output_column_is_refused_before_the_run_folder_is_written(tmp_path, capsys):
    data = _csv(tmp_path / "flat.csv", y=lambda t: 2.5)
    out = tmp_path / "run"
    argv = ["train", str(data), *CSV, *TINY, "--window", "2", "--cubic", "0", "--out", str(out)]
    one_line_error(capsys, main(argv), "flat.csv", "output column 'y' is constant")
    assert not out.exists()
