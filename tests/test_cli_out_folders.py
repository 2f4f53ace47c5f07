"""``--out`` means one thing in every command that writes a folder: a new or empty folder, or
one canonid wrote there, is written; a folder of other files is refused in one line before any
work, and its files are left as they were."""

from __future__ import annotations

import pytest
from cli_helpers import one_line_error

from canonid.cli import main

#: a command line of each command that writes a folder, --out DIR added by the test
COMMANDS = {
    "generate": ["generate", "tank", "--n-train", "1", "--n-val", "1", "--n-test", "1"],
    "train": ["train", "{csv}", "--inputs", "u", "--outputs", "y", "--window", "2"],
    "analyze": ["analyze", "tank", "--window", "2", "--trials", "1"],
    "reproduce": ["reproduce", "--systems", "tank"],
}


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_folder_of_other_files_is_refused_in_one_line(name, tmp_path, capsys):
    csv = tmp_path / "d.csv"
    csv.write_text("t,u,y\n" + "".join(f"{i},{i % 3},{i % 5}\n" for i in range(40)))
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes\n")
    argv = [word.format(csv=csv) for word in COMMANDS[name]]
    code = main([*argv, "--out", str(out), "--no-progress"])
    one_line_error(capsys, code, f"canonid {name}: error: --out {out}", "notes.txt")
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert (out / "notes.txt").read_text() == "my notes\n"
