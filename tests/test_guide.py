"""The user guide reads as a guide: a short README with one number per table cell, how-to pages
in the present tense (history lives in the studies and the records), and each of the six
contradictions of issue 52 pinned to the one source that now speaks for it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = (ROOT / "README.md").read_text(encoding="utf-8")
NUMBER = re.compile(r"(?<![\w.])[−-]?\d[\d,]*(?:\.\d+)?(?:e[−-]?\d+)?(?![\w])")
MARKER = re.compile(r"<!-- figure: [\w./-]+ -->")

#: words and forms that tell history rather than what canonid does
HISTORY = re.compile(
    r"\b(before the|was|were|earlier|instead of|previously|no longer|used to)\b"
    r"|\b20\d\d-\d\d-\d\d\b",
    re.IGNORECASE,
)
#: the how-to pages held to the present tense: every page but the Results page, the index of
#: records, the changelog and the studies, which may tell what a run did and when
NOT_HOW_TO = {"results.md", "benchmark-records.md", "changelog.md"}
HOW_TO = sorted(p.name for p in DOCS.glob("*.md") if p.name not in NOT_HOW_TO)


def history(text: str) -> list[str]:
    """The lines of ``text`` (outside code blocks and HTML comments) with a history word."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
    text = re.sub(r"`[^`\n]*`", "", text)  # inline code: commands, keys, examples
    return [line for line in text.splitlines() if HISTORY.search(line)]


def test_readme_is_short_and_has_few_figures():
    assert len(README.splitlines()) <= 100
    assert len(MARKER.findall(README)) <= 5


def test_readme_table_cells_hold_one_number_each():
    for line in README.splitlines():
        if line.startswith("|") and not re.match(r"^\|[-:| ]+\|$", line):
            for cell in line.strip("|").split("|"):
                assert len(NUMBER.findall(MARKER.sub("", cell))) <= 1, cell


def test_readme_names_no_study_command_and_the_two_quick_start_commands():
    assert "benchmarks/" not in README and "python benchmarks" not in README
    quick = README.split("## Quick start")[1].split("```bash")[1].split("```")[0]
    assert [line.split("#")[0].strip() for line in quick.strip().splitlines()] == [
        "make demo",
        "make test",
    ]


@pytest.mark.parametrize("page", HOW_TO)
def test_how_to_pages_hold_no_history(page: str):
    assert len(HOW_TO) >= 15
    found = history((DOCS / page).read_text(encoding="utf-8"))
    assert not found, f"{page}: {found}"


def test_a_planted_history_sentence_fails():
    page = (DOCS / "getting-started.md").read_text(encoding="utf-8")
    assert history(page) == []
    for planted in (
        "The defaults before the cubic branch scored higher.",
        "It took 10.6 minutes instead of 12.1.",
        "The window was 20.",
        "Measured on 2026-11-29.",
        "An earlier profile trained longer.",
    ):
        assert history(page + "\n" + planted + "\n") == [planted], planted


def _quotes(key: str) -> list[str]:
    pages = [ROOT / "README.md", *DOCS.rglob("*.md")]
    return [p.name for p in pages if f"<!-- figure: {key} -->" in p.read_text(encoding="utf-8")]


def test_silverbox_cpu_has_one_source():
    # the command's CPU on an idle machine; the run beside other jobs stays in its record
    assert "results.md" in _quotes("benchmark/silverbox/cpu-min")
    assert _quotes("candidates/side/cpu") == []


def test_make_demo_time_is_the_record_with_its_machine():
    results = (DOCS / "results.md").read_text(encoding="utf-8")
    assert "<!-- figure: demo/wall -->" in results
    pages = [results, README, *(p.read_text(encoding="utf-8") for p in DOCS.glob("*.md"))]
    assert not any("within its\n10 minutes" in t or "within its 10 minutes" in t for t in pages)
    assert "10 minutes" not in results and "10 minutes" not in README


def test_the_paper_model_at_l10_has_one_score_on_the_pages():
    # Table 1's score; the compression study's own score of that model stays in its record
    assert "README.md" in _quotes("demo/t1/mlp-paper/10/y")
    assert _quotes("demo/compression/30/full") == []


def test_the_tank_defaults_come_from_table_1():
    # the README quotes the make demo record's defaults column, as the Results page does
    assert "<!-- figure: demo/t1/mlp-defaults/10/y -->" in README
    assert "<!-- figure: defaults/tank/0 -->" not in README


def test_analyze_help_names_only_files_analyze_writes():
    import argparse

    from canonid.cli import build_parser

    parser = build_parser("analyze")
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    text = sub.choices["analyze"].description
    named = set(re.findall(r"[\w]+\.(?:json|png|pdf|svg)", text))
    source = (ROOT / "canonid" / "theory.py").read_text(encoding="utf-8")
    assert named == {"analysis.json", "learned_analysis.json"}, named
    assert all(f'"{name}"' in source for name in named)
    assert "bound_vs_window" in text and 'f"bound_vs_window.{request.figure_format}"' in source


def test_reduce_sweep_labels_name_the_split_scored(tmp_path):
    # data without a test split are scored on validation: the sweep's table and figures say so
    from matplotlib.figure import Figure

    from canonid import reduction

    one = reduction.ReductionResult(
        **dict.fromkeys(("source", "out", "model", "stopped"), "runs/a"),
        **dict.fromkeys(("window", "seed", "state_dim", "latent_dim", "rollout_horizon"), 2),
        **dict.fromkeys(("best_epoch", "epochs_run"), 1),
        **dict.fromkeys(("compression", "reconstruction_mse", "rollout_mse", "seconds"), 0.5),
        full_rollout_mse=0.4,
        rollout_mse_clean=None,
        full_rollout_mse_clean=None,
        recipe={},
        split="val",
    )
    labels: list[str] = []

    def save(fig: Figure, path):
        ax = fig.axes[0]
        labels.extend([ax.get_title(), ax.get_ylabel()])
        return path

    import pytest

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(reduction, "_save", save)
        reduction.plot_heatmap([one], tmp_path / "h.png")
        reduction.plot_reduced_mse([one], tmp_path / "m.png")
    assert reduction.scored_on([one]) == "val"
    assert "(val, normalised" in labels[0] and "(val, physical" in labels[3]
    assert not any("test" in label for label in labels)
