"""Every figure README.md and docs/ quote agrees with the record that measured it, the site's
formulas are MathML written at build time, and its header names canonid's version."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted(p for p in (ROOT / "docs").rglob("*.md"))]


def _hook(name: str):
    spec = importlib.util.spec_from_file_location(
        f"docs_hook_{name}", ROOT / "docs/hooks" / f"{name}.py"
    )
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


figures = _hook("figures")


def test_every_quoted_figure_agrees_with_its_source():
    problems = [p for page in PAGES for p in figures.check(page.read_text("utf-8"), page.name)]
    assert not problems, "\n".join(problems)


def test_the_headline_figures_are_checked():
    readme = (ROOT / "README.md").read_text("utf-8")
    for key in ("defaults/tank/0", "defaults/silverbox/2", "demo/wall", "quick/train/epochs"):
        assert f"<!-- figure: {key} -->" in readme, key


def test_a_figure_that_disagrees_with_its_source_fails():
    tank = figures.value("defaults/tank/0")  # 7.52e-05 in the defaults study
    assert figures.check(f"tank {float(tank):.2e}<!-- figure: defaults/tank/0 -->", "p") == []
    wrong = figures.check("tank 1.12e-4<!-- figure: defaults/tank/0 -->", "p.md")
    assert wrong == [f"p.md:1: '1.12e-4' quotes defaults/tank/0, whose source says {tank}"]
    unknown = figures.check("x 3<!-- figure: no/such/key -->", "p.md")
    assert unknown and "no figure 'no/such/key'" in unknown[0]
    demo = figures.value("demo/wall")
    assert figures.check(f"takes {demo}<!-- figure: demo/wall -->", "p") == []
    assert figures.check("takes about 8 min<!-- figure: demo/wall -->", "p")


def test_figures_from_prose_and_from_inside_a_cell():
    import pytest

    # the screen lines of the overflow tanks state where the full run ended only in their text
    ended, budget = (figures.value(f"overflow/full/l10/{k}") for k in ("ended", "budget"))
    assert ended.isdigit() and budget.isdigit() and int(ended) <= int(budget)
    with pytest.raises(KeyError, match="no text matching"):
        figures.Prose("Overflow tanks", r"no such figure (\d+)").value()
    # "0.04527 (0.1376; 243 s)": score, best validation loss, CPU seconds
    cell = figures.FIGURES["arx-start/drone2d/0"]
    assert [cell._replace(pick=i).value() for i in (0, 1)] == ["0.04527", "0.1376"]


def test_rounding_to_the_quoted_digits():
    assert figures.agrees("0.385", "0.3855") and figures.agrees("7.5e-5", "7.52e-05")
    assert not figures.agrees("0.386", "0.3845") and not figures.agrees("7.53e-5", "7.52e-05")
    assert figures.agrees("9,000", "9000") and not figures.agrees("50", "100")


def test_code_figures_follow_the_profile():
    from canonid.profiles import PROFILES

    assert figures.value("quick/train/horizon") == str(PROFILES["quick"]["train"]["horizon"])


def test_formulas_become_mathml_and_code_stays():
    math = _hook("mathml")
    page = "a $\\alpha_\\ell$ b `$x$` $5 or $10\n\n```bash\necho $PWD $y$\n```\n<!-- $z$ -->\n"
    out = math.render(page)
    assert out.count("<math") == 1 and "<msub><mi>&#x003B1;</mi>" in out
    assert "`$x$`" in out and "echo $PWD $y$" in out and "<!-- $z$ -->" in out
    assert "$5 or $10" in out
    assert "|" not in math.render("$|x|$").split("<math", 1)[1]  # a pipe would end a table cell
    block = math.render("$$\nx_{t+1} = f(x_t)\n$$")
    assert 'display="block"' in block


def test_the_header_names_the_version():
    from canonid import __version__

    header = _hook("site_header")
    config = header.on_config({"site_name": "canonid", "repo_url": None})
    assert config["site_name"] == f"canonid {__version__}"
