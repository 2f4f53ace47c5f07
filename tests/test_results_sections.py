"""benchmarks/_results.py: a script rewrites its own section, the notes file beside its record,
and nothing else, and the notes a person added to that section stay."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import _results


def _sections(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith("<!-- ")]


def test_a_rewritten_section_keeps_its_hand_notes_and_the_other_sections(tmp_path, monkeypatch):
    monkeypatch.setattr(_results, "BENCHMARKS", tmp_path)
    (tmp_path / "studies" / "b").mkdir(parents=True)
    (tmp_path / "studies" / "b" / "section-b.md").write_text("")  # beside a study's record
    _results.write_section("Section A", "table one", command="python a.py")
    _results.write_section("Section B", "table of B", command="python b.py")
    a_file = tmp_path / "records" / "section-a.md"
    b_file = tmp_path / "studies" / "b" / "section-b.md"
    note = f"{_results.HAND_NOTE} (2026-01-01): the runs were trained\nbeside another job.\n"
    text = a_file.read_text()
    a_file.write_text(
        text.replace(
            "table one\n<!-- END Section A -->", f"table one\n{note}<!-- END Section A -->"
        )
    )

    _results.write_section("Section A", "table two", command="python a.py")
    text = a_file.read_text()
    a = text[text.index("<!-- BEGIN Section A -->") : text.index("<!-- END Section A -->")]
    assert "table two" in a and "table one" not in a
    assert a.endswith(note)  # the note, after the new text, once
    assert text.count(_results.HAND_NOTE) == 1
    assert "table of B" in b_file.read_text() and "table of B" not in text
    assert _sections(text) == ["<!-- BEGIN Section A -->", "<!-- END Section A -->"]
    assert _results.read_section("Section B").startswith("<!-- BEGIN Section B -->")


def test_a_section_without_notes_is_the_new_text_alone(tmp_path, monkeypatch):
    monkeypatch.setattr(_results, "BENCHMARKS", tmp_path)
    _results.write_section("A", "first", command="python a.py")
    _results.write_section("A", "second", command="python a.py")
    text = (tmp_path / "records" / "a.md").read_text()
    assert "first" not in text and text.rstrip().endswith("second\n<!-- END A -->")


def test_every_quoted_cell_figure_is_its_cell_in_the_record():
    import json

    root = Path(__file__).resolve().parents[1] / "benchmarks"
    checked = 0
    for path in root.rglob("*.json"):
        record = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(record, dict):
            continue
        for key, figure in record.get("figures", {}).items():
            if isinstance(figure, dict):
                assert _results.cell_value(record["tables"], figure) == figure["value"], key
                checked += 1
    assert checked > 300


def test_a_script_run_rewrites_its_record_and_the_figures_follow_their_cells(tmp_path, monkeypatch):
    import json

    monkeypatch.setattr(_results, "BENCHMARKS", tmp_path)
    (tmp_path / "records").mkdir()
    figure = {"value": "1.5", "table": 0, "row": {"model": "mlp"}, "column": "MSE"}
    old = {"study": "T", "figures": {"t/mlp": figure, "t/typed": "7"}, "tables": []}
    (tmp_path / "records" / "t.json").write_text(json.dumps(old))
    table = "| model | MSE |\n|---|---:|\n| arx | 9.0 |\n| mlp | **2.25** |\n"
    body = f"Load average 0.5 at the start.\n\n{table}"
    _results.write_section("T", body, command="python t.py")
    record = json.loads((tmp_path / "records" / "t.json").read_text())
    assert record["figures"]["t/mlp"]["value"] == "2.25"  # read again from its cell
    assert record["figures"]["t/typed"] == "7"
    assert record["command"] == "python t.py" and record["load"].startswith("Load average 0.5")
    assert record["tables"] == [
        {"columns": ["model", "MSE"], "rows": [["arx", "9.0"], ["mlp", "**2.25**"]]}
    ]
    assert {"commit", "date", "machine"} <= set(record)
    _results.write_section("New", "| a |\n|---|\n| 1 |\n", command="python n.py")
    assert json.loads((tmp_path / "records" / "new.json").read_text())["tables"][0]["rows"] == [
        ["1"]
    ]
