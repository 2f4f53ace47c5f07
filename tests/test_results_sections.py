"""benchmarks/_results.py: a script rewrites its own section of RESULTS.md and nothing else, and
the notes a person added to that section stay."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import _results


def _sections(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith("<!-- ")]


def test_a_rewritten_section_keeps_its_hand_notes_and_the_other_sections(tmp_path, monkeypatch):
    results = tmp_path / "RESULTS.md"
    monkeypatch.setattr(_results, "RESULTS", results)
    _results.write_section("A", "table one", command="python a.py")
    _results.write_section("B", "table of B", command="python b.py")
    note = f"{_results.HAND_NOTE} (2026-01-01): the runs were trained\nbeside another job.\n"
    text = results.read_text()
    results.write_text(
        text.replace("table one\n<!-- END A -->", f"table one\n{note}<!-- END A -->")
    )

    _results.write_section("A", "table two", command="python a.py")
    text = results.read_text()
    a = text[text.index("<!-- BEGIN A -->") : text.index("<!-- END A -->")]
    assert "table two" in a and "table one" not in a
    assert a.endswith(note)  # the note, after the new text, once
    assert text.count(_results.HAND_NOTE) == 1
    assert "table of B" in text
    assert _sections(text) == [
        "<!-- BEGIN A -->",
        "<!-- END A -->",
        "<!-- BEGIN B -->",
        "<!-- END B -->",
    ]


def test_a_section_without_notes_is_the_new_text_alone(tmp_path, monkeypatch):
    results = tmp_path / "RESULTS.md"
    monkeypatch.setattr(_results, "RESULTS", results)
    _results.write_section("A", "first", command="python a.py")
    _results.write_section("A", "second", command="python a.py")
    text = results.read_text()
    assert "first" not in text and text.rstrip().endswith("second\n<!-- END A -->")
