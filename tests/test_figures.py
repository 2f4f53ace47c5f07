"""Every figure README.md and docs/ quote agrees with the JSON record that measured it, each
rendered table matches its record, the site's
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
    for key in ("demo/t1/mlp-defaults/10/y", "demo/t1/mlp-paper/10/y", "paper/t1/tank/mlp/10"):
        assert f"<!-- figure: {key} -->" in readme, key


def test_a_figure_that_disagrees_with_its_record_fails():
    tank = figures.value("defaults/tank/0")  # 7.52e-05 in the defaults study's record
    assert figures.check(f"tank {float(tank):.2e}<!-- figure: defaults/tank/0 -->", "p") == []
    wrong = figures.check("tank 1.12e-4<!-- figure: defaults/tank/0 -->", "p.md")
    assert wrong == [f"p.md:1: '1.12e-4' quotes defaults/tank/0, its record: {tank}"]
    unknown = figures.check("x 3<!-- figure: no/such/key -->", "p.md")
    assert unknown and "no figure 'no/such/key'" in unknown[0]
    demo = figures.value("demo/wall")
    assert figures.check(f"takes {demo}<!-- figure: demo/wall -->", "p") == []
    assert figures.check("takes about 8 min<!-- figure: demo/wall -->", "p")
    assert figures.check("<!-- table: records/no-such-record 0 -->", "p")


def test_every_record_names_what_measured_it():
    for name, record in figures.records().items():
        if "figures" in record:
            assert {"command", "commit", "machine", "load", "figures"} <= set(record), name
            assert record.get("source") or record.get("commit"), name


def _parse(markdown: str) -> tuple[list[str], list[list[str]]]:
    """A rendered table back into (columns, rows)."""
    lines = [line for line in markdown.splitlines() if line.startswith("| ")]
    cells = [[c.strip().replace("\\|", "|") for c in line[2:-2].split(" | ")] for line in lines]
    return cells[0], cells[2:]


def test_each_rendered_table_matches_its_record():
    pages = [page.read_text("utf-8") for page in PAGES]
    used = [(m["name"], int(m["nth"])) for text in pages for m in figures.TABLE.finditer(text)]
    assert used, "no page renders a table from a record"
    for name, nth in used:
        columns, rows = _parse(figures.render(name, nth))
        body = figures.records()[name]
        assert body["command"] in figures.render(name, nth).replace("`", "")
        if "tables" not in body:  # a suite record: one row per record, RMSE and CPU per contestant
            for row, (record, cells) in zip(rows, body["records"].items(), strict=False):
                assert row[0] == record
                for i, who in enumerate(body["contestants"]):
                    assert row[1 + 2 * i] == format(cells[who]["rmse"], ".4g"), (name, record)
                    assert row[2 + 2 * i] == format(cells[who]["cpu_seconds"], ".0f")
            assert len(rows) == len(body["records"]) + 1, name  # and the means
            continue
        record = body["tables"][nth]
        assert columns == record["columns"] and rows == record["rows"], (name, nth)


def test_a_suite_record_renders_its_contestants_and_means(tmp_path, monkeypatch):
    import json

    cell = {"rmse": 0.5, "cpu_seconds": 12.3, "finite": True}
    suite = {
        "command": "python benchmarks/suite.py",
        "commit": "abc1234",
        "machine": {"processor": "x86_64", "cores": 2},
        "load": {"before": 0.1, "after": 0.2},
        "records": {
            "tank": {"character": "c", "a": cell, "b": {**cell, "finite": False}},
            "drone": {
                "character": "d",
                "a": cell,
                "b": {"rmse": None, "cpu_seconds": None, "finite": False},
            },
        },
        "contestants": {"a": {}, "b": {}},
        "means": {
            "a": {"rmse_geomean": 0.5, "cpu_seconds": 24.6, "all_finite": True},
            "b": {"rmse_geomean": None, "cpu_seconds": 12.3, "all_finite": False},
        },
    }
    (tmp_path / "suite.json").write_text(json.dumps(suite))
    monkeypatch.setattr(figures, "BENCHMARKS", tmp_path)
    figures.records.cache_clear()
    try:
        columns, rows = _parse(figures.render("suite"))
        assert columns == ["record", "a RMSE", "a CPU s", "b RMSE", "b CPU s"]
        assert rows[0] == ["tank", "0.5", "12", "not finite", "12"]
        assert rows[1] == ["drone", "0.5", "12", "not finite", "—"]  # a failed training
        assert rows[2][1:] == ["0.5", "25", "—", "12"]
    finally:
        figures.records.cache_clear()


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
