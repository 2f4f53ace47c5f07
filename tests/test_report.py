"""The report builder: Markdown with relative figure links, self-contained HTML."""

import base64

import pytest

from canonid.report import Report


def test_markdown_and_html(tmp_path):
    fig = tmp_path / "figs" / "a.png"
    fig.parent.mkdir()
    fig.write_bytes(b"\x89PNG fake")
    r = Report("Title <x>")
    r.heading("Table 1")
    r.table(["ℓ", "MSE | ours"], [[5, "1.0e-4"]], caption="cap")
    r.figure(fig, "rollouts")
    r.link(tmp_path / "metrics.json", "metrics")
    md, page = r.write(tmp_path / "out")
    text = md.read_text()
    assert "# Title <x>" in text
    assert "| ℓ | MSE \\| ours |" in text and "| 5 | 1.0e-4 |" in text
    assert "![rollouts](../figs/a.png)" in text
    assert "[metrics](../metrics.json)" in text
    h = page.read_text()
    assert "Title &lt;x&gt;" in h
    assert base64.b64encode(fig.read_bytes()).decode() in h


def test_bad_table_row():
    r = Report("t")
    with pytest.raises(ValueError, match="row 0 has 1 cells"):
        r.table(["a", "b"], [[1]])


def test_report_settings_are_written_in_words_and_numbers_align_right(tmp_path):
    from canonid.report import Report
    from canonid.reproduce_report import _settings_text

    text = _settings_text(
        {"lr_final": None, "grad_clip": 1.0, "X": [[0.05, 0.05], [5.0, 5.0]], "windows": [5, 10]}
    )
    assert text == "lr final = none; grad clip = 1; X = [0.05, 5] × [0.05, 5]; windows = 5, 10"
    report = Report("t")
    report.table(["stage", "MSE"], [["training", "1.5e-4"]])
    html = report.to_html(tmp_path)
    assert "<td>training</td>" in html and '<td class="n">1.5e-4</td>' in html
