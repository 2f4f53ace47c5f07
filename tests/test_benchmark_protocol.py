"""The standard benchmarks' protocol and published results, pinned against BASELINES.md.

``../shared/data/BASELINES.md`` (beside the repository) holds the scoring protocol of
``nonlinear_benchmarks`` 1.0.1 and the published results of Champneys et al. (2024), with
sources. Its tables are copied below (``PUBLISHED``), so a checkout without ``shared/`` still
checks every ``n_init``, split, figure and best mark of :data:`BENCHMARKS`; where the file exists,
the same checks run on it. The parser is strict: a cell it cannot read, a row too short or too
long, or any changed digit fails. The two benchmarks that file does not cover (Bouc–Wen, F-16:
:data:`ADDED`) are pinned against the table of the same form in ``docs/benchmarks.md``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from test_benchmarks import EXPECTED

from canonid.benchmark import BenchmarkReport, PartScore, report_table
from canonid.datagen.benchmarks import BENCHMARKS, CHAMPNEYS, baselines_markdown

ROOT = Path(__file__).resolve().parents[1]
BASELINES_MD = ROOT.parent / "shared" / "data" / "BASELINES.md"
DOCS = ROOT / "docs" / "benchmarks.md"

# BASELINES.md's tables and its last paragraph, as copied from the file
PUBLISHED = """
| benchmark | train / test | n_init (1.0.0 → 1.0.1) | sampling | units |
|---|---|---|---|---|
| Cascaded Tanks | `uEst/yEst` / `uVal/yVal` (1,024 samples each) | 5 → **50** | `Ts` from the file (4 s) | V |
| CED | two records of 500 samples, train `[:400]`, test `[400:]` of each | 4 → **10** | 0.02 s | ticks/s |
| EMPS | `DATA_EMPS` / `DATA_EMPS_PULSES` | 20 → 20 | from the file | mm |
| Wiener–Hammerstein | `5200:184000`: first 100,000 train, last 78,800 test | 50 → 50 | 1/51200 s | mV |
| Silverbox | multisine `40650:127400`, first 75 % train, rest test; arrow full `100:40575`, arrow no-extrapolation its first 32,000 | 50 → 50 | 1/610.35 s | mV |

## Baseline study: Champneys, Beintema, Tóth, Schoukens, Rogers (2024)

"Baseline results for selected nonlinear system identification benchmarks", arXiv:2405.10779;

| method | SB multisine [mV] | SB arrow full [mV] | SB arrow no-extrap. [mV] | WH [mV] | EMPS [mm] | CT [V] | CED test 1 | CED test 2 |
|---|---|---|---|---|---|---|---|---|
| LTI state space | 6.96 | 14.4 | 6.58 | 43.4 | 5.53 | 0.588 | 0.224 | 0.384 |
| LTI ARX | 6.95 | 14.2 | 6.59 | 43.4 | 12.6 | 0.685 | 0.291 | 0.331 |
| polynomial NARX | 0.640 | 2.25 | 0.571 | 27.3 | 5.17 | 0.413 | 0.10 | 0.141 |
| GP NARX | 0.301 | 0.60 | 0.259 | 23.1 | 1690 | 0.622 | 0.102 | 0.090 |
| MLP NARX | 2.80 | 5.18 | 2.40 | 310 | 133 | 2.04 | 0.142 | 0.101 |
| MLP FIR | 18.9 | 20.2 | 15.3 | 24.8 | 121 | 1.43 | 0.122 | 0.095 |
| RNN | 1.64 | 4.88 | 1.73 | 6.87 | 89.2 | 0.543 | 0.096 | 0.235 |
| GRU | 1.49 | 2.80 | 0.947 | 3.97 | 220 | 0.396 | 0.286 | 0.238 |
| LSTM | 1.50 | 2.68 | 0.960 | 4.45 | 74.1 | 0.490 | 0.303 | 0.145 |
| OLSTM | 1.51 | 2.38 | 1.08 | 4.55 | 111 | 0.471 | 0.151 | 0.259 |

## Best published results (the same paper's state-of-the-art table, with its sources)

| method (source) | SB multisine | SB arrow full | SB no-extrap. | WH | EMPS | CT | CED 1 | CED 2 |
|---|---|---|---|---|---|---|---|---|
| DT SUBNET (Beintema et al., 2021) | 0.36 | 1.4 | 0.32 | 0.241 | – | 0.37 | 0.169 | 0.117 |
| CT SUBNET (Beintema et al., 2023) | – | – | – | – | 4.61 | 0.306 | 0.115 | 0.074 |
| grey box (Worden et al., 2018) | – | – | – | – | – | 0.191 | – | – |
| PNLSS (Paduart et al., 2010; Relan et al., 2017) | – | 0.26 | – | 0.42 | – | 0.45 | – | – |
| TSEM (Forgione and Piga, 2021a) | – | – | – | – | – | 0.33 | – | – |
| SCI (Forgione and Piga, 2021a) | – | – | – | – | – | 0.4 | – | – |
| dynoNet (Forgione and Piga, 2021b) | – | – | – | 0.452 | 2.64 | – | – | – |

The lowest published figure per column is the bar to beat: SB multisine 0.301 (GP NARX), arrow
full 0.26 (PNLSS), no-extrapolation 0.259 (GP NARX), WH 0.241, EMPS 2.64, CT 0.191, CED 0.096 /
0.074.
"""  # noqa: E501 — the tables as the file writes them, one row a line

# BASELINES.md's names → the registry's: benchmarks, and the test part of each results column
BENCH = {
    "Cascaded Tanks": "cascaded-tanks",
    "CED": "ced",
    "EMPS": "emps",
    "Wiener–Hammerstein": "wiener-hammerstein",
    "Silverbox": "silverbox",
}
COLUMN = {
    "SB multisine": ("silverbox", "multisine"),
    "SB arrow full": ("silverbox", "arrow-full"),
    "SB arrow no-extrap.": ("silverbox", "arrow-no-extrapolation"),
    "SB no-extrap.": ("silverbox", "arrow-no-extrapolation"),
    "WH": ("wiener-hammerstein", "test"),
    "EMPS": ("emps", "DATA_EMPS_PULSES"),
    "CT": ("cascaded-tanks", "validation"),
    "CED test 1": ("ced", "low-amplitude"),
    "CED 1": ("ced", "low-amplitude"),
    "CED test 2": ("ced", "high-amplitude"),
    "CED 2": ("ced", "high-amplitude"),
}
FIGURE = re.compile(r"\d+(?:\.\d+)?")
#: the benchmarks BASELINES.md does not cover: their protocol is docs/benchmarks.md's table, and
#: no published figure is entered for them
ADDED = {"Bouc–Wen": "bouc-wen", "F-16": "f16-gvt"}


def _tables(text: str) -> dict[str, list[list[str]]]:
    """Every Markdown table of ``text`` by its first header cell: header row, then body rows."""
    tables: dict[str, list[list[str]]] = {}
    for block in re.findall(r"(?:^\|.*\|[ \t]*\n?)+", text, flags=re.M):
        rows = [[c.strip() for c in line.strip()[1:-1].split("|")] for line in block.splitlines()]
        header, rule, *body = rows
        assert all(re.fullmatch(r"-{3,}", c) for c in rule), f"not a table rule: {rule}"
        for row in body:
            assert len(row) == len(header), f"{row} has {len(row)} cells, the header {len(header)}"
        tables[header[0]] = [header, *body]
    return tables


def _figures(text: str) -> dict[tuple[str, str, str], tuple[str, str | None]]:
    """Each published figure: (benchmark, test part, method) → (figure, its source's reference
    in the best-results table, None for the baseline study)."""
    tables = _tables(text)
    out = {}
    for first, pattern in (
        ("method", r"(?P<m>.+)"),
        ("method (source)", r"(?P<m>.+?) \((?P<r>.+)\)"),
    ):
        header, *body = tables[first]
        columns = []
        for cell in header[1:]:  # "SB multisine [mV]": the column, in the scoring units
            name, units = re.fullmatch(r"(.+?)(?: \[(.+)\])?", cell).groups()
            columns.append(COLUMN[name])
            assert units in (None, BENCHMARKS[COLUMN[name][0]].score_units), cell
        for row in body:
            method = re.fullmatch(pattern, row[0])
            assert method, f"unreadable method cell {row[0]!r}"
            for (bench, test), cell in zip(columns, row[1:], strict=True):
                assert FIGURE.fullmatch(cell) or cell == "–", f"unreadable figure {cell!r} in {row}"
                if cell != "–":
                    out[(bench, test, method["m"])] = (cell, method.groupdict().get("r"))
    return out


def _protocol(text: str) -> dict[str, dict]:
    """Each benchmark's n_init (1.0.1), units, sampling time (None: read from the file) and
    sample ranges ``[start, stop)`` of its training records and test parts (stop None: to the
    record's end), read from the protocol table's cells."""
    header, *body = _tables(text)["benchmark"]
    assert header == ["benchmark", "train / test", "n_init (1.0.0 → 1.0.1)", "sampling", "units"]
    out = {}
    for title, split, n_init, sampling, units in body:
        name = BENCH[title]
        new = re.fullmatch(r"\d+ → (?:\*\*)?(\d+)(?:\*\*)?", n_init)
        assert new, f"unreadable n_init {n_init!r}"
        out[name] = {
            "n_init": int(new.group(1)),
            "units": units,
            "dt": _sampling(sampling),
            **_split(name, split),
        }
    return out


def _sampling(cell: str) -> float | None:
    if cell == "from the file":
        return None
    for pattern, value in (
        (r"1/([\d.]+) s", lambda x: 1 / float(x)),
        (r"`Ts` from the file \(([\d.]+) s\)", float),
        (r"([\d.]+) s", float),
    ):
        if m := re.fullmatch(pattern, cell):
            return value(m.group(1))
    raise AssertionError(f"unreadable sampling {cell!r}")


def _int(text: str) -> int:
    return int(text.replace(",", ""))


def _split(name: str, cell: str) -> dict[str, list[tuple[int, int | None]]]:
    """The training and test ranges a protocol cell states, in the package's order."""
    patterns = {
        "cascaded-tanks": r"`uEst/yEst` / `uVal/yVal` \(([\d,]+) samples each\)",
        "ced": r"two records of (\d+) samples, train `\[:(\d+)\]`, test `\[(\d+):\]` of each",
        "emps": r"`DATA_EMPS` / `DATA_EMPS_PULSES`",
        "wiener-hammerstein": r"`(\d+):(\d+)`: first ([\d,]+) train, last ([\d,]+) test",
        "silverbox": (
            r"multisine `(\d+):(\d+)`, first (\d+) % train, rest test; arrow full `(\d+):(\d+)`, "
            r"arrow no-extrapolation its first ([\d,]+)"
        ),
    }
    m = re.fullmatch(patterns[name], cell)
    assert m, f"{name}: unreadable train / test cell {cell!r}"
    g = [_int(x) for x in m.groups()]
    if name == "cascaded-tanks":
        return {"train": [(0, g[0])], "test": [(0, g[0])]}
    if name == "ced":
        n, train_stop, test_start = g
        return {"train": [(0, train_stop)] * 2, "test": [(test_start, n)] * 2}
    if name == "emps":
        return {"train": [(0, None)], "test": [(0, None)]}
    if name == "wiener-hammerstein":
        lo, hi, n_train, n_test = g
        assert n_train + n_test == hi - lo, f"{cell!r}: the two parts do not fill {lo}:{hi}"
        return {"train": [(lo, lo + n_train)], "test": [(hi - n_test, hi)]}
    lo, hi, percent, arrow_lo, arrow_hi, no_extrapolation = g
    cut = lo + int(percent / 100 * (hi - lo))
    test = [(cut, hi), (arrow_lo, arrow_hi), (arrow_lo, arrow_lo + no_extrapolation)]
    return {"train": [(lo, cut)], "test": test}


def _bar(text: str) -> list[str]:
    """The figures of the closing 'bar to beat' sentence, in the columns' order."""
    m = re.search(r"bar to beat:(.*?)\.\s*$", text, flags=re.S)
    assert m, "no 'bar to beat' sentence"
    return re.findall(r"(?<![\w.])\d+(?:\.\d+)?(?![\w.])", m.group(1))


def _texts() -> list:
    file = pytest.param(
        BASELINES_MD,
        id="shared/data/BASELINES.md",
        marks=pytest.mark.skipif(
            not BASELINES_MD.is_file(), reason=f"{BASELINES_MD} is not in this checkout"
        ),
    )
    return [pytest.param(None, id="copy in this file"), file]


def _read(path: Path | None) -> str:
    return PUBLISHED if path is None else path.read_text(encoding="utf-8")


def _check_protocol(text: str) -> None:
    protocol = _protocol(text)
    assert set(protocol) == set(BENCHMARKS) - set(ADDED.values())
    _check_stated(protocol)


def _check_stated(protocol: dict[str, dict]) -> None:
    for name, stated in protocol.items():
        bench, expected = BENCHMARKS[name], EXPECTED[name]
        assert stated["n_init"] == bench.n_init == expected["n_init"], name
        assert stated["units"] == bench.score_units == expected["score"][0], name
        assert stated["dt"] is None or stated["dt"] == pytest.approx(expected["dt"], rel=1e-12)
        for role, parts in (("train", expected["train"]), ("test", expected["test"])):
            ranges = [tuple(part[-2:]) for part in parts]  # EXPECTED's (…, start, stop)
            assert len(stated[role]) == len(ranges), (name, role)
            for (start, stop), (want_start, want_stop) in zip(stated[role], ranges):
                assert start == want_start and stop in (None, want_stop), (name, role)


def _check_figures(text: str) -> None:
    published = _figures(text)
    entered = {(n, b.test, b.method): b for n, bench in BENCHMARKS.items() for b in bench.baselines}
    assert set(entered) == set(published)
    for key, (figure, reference) in published.items():
        b = entered[key]
        assert (b.figure, b.units) == (figure, BENCHMARKS[key[0]].score_units), key
        assert b.rmse == float(figure) and b.test in BENCHMARKS[key[0]].test_parts
        if reference is None:
            assert b.source == CHAMPNEYS and "arXiv:2405.10779" in CHAMPNEYS
        else:
            assert b.source.startswith(reference) and "Champneys" in b.source, key


def _check_best(text: str) -> None:
    lowest: dict[tuple[str, str], str] = {}
    for (bench, test, _), (figure, _) in _figures(text).items():
        lowest[(bench, test)] = min(lowest.get((bench, test), figure), figure, key=float)
    marked = {
        (n, b.test): b.figure for n, bench in BENCHMARKS.items() for b in bench.baselines if b.best
    }
    assert marked == lowest
    # the file's own closing sentence names the same figures, in its columns' order
    assert _bar(text) == [lowest[c] for c in dict.fromkeys(COLUMN.values())]


@pytest.mark.parametrize("path", _texts())
def test_n_init_units_sampling_and_splits_are_version_1_0_1s(path):
    _check_protocol(_read(path))


def test_the_1_0_1_changes_are_cascaded_tanks_and_ced():
    assert {name: b.n_init for name, b in BENCHMARKS.items()} == {
        "cascaded-tanks": 50,
        "silverbox": 50,
        "wiener-hammerstein": 50,
        "emps": 20,
        "ced": 10,
        "bouc-wen": 50,  # canonid's: the package sets none
        "f16-gvt": 50,
    }


def _added_protocol(text: str) -> dict[str, dict]:
    """docs/benchmarks.md's protocol table of :data:`ADDED`, read as :func:`_protocol` reads
    BASELINES.md's: n_init, units, sampling time and the records of each split."""
    header, *body = _tables(text)["benchmark"]
    assert header == ["benchmark", "train / test", "n_init", "sampling", "units"]
    patterns = {
        "bouc-wen": (
            r"`(BoucWen_train\.mat)` \(`u`, `y`\), simulated by the user / `(multisine)` and "
            r"`(sinesweep)` \(`uval_\*`, `yval_\*`\), whole records"
        ),
        "f16-gvt": (
            r"full multisine, levels (\d), (\d), (\d), (\d) / levels (\d), (\d), (\d) "
            r"\(`_Validation`\), whole records"
        ),
    }
    out = {}
    for title, split, n_init, sampling, units in body:
        name = ADDED[title]
        m = re.fullmatch(patterns[name], split)
        assert m, f"{name}: unreadable train / test cell {split!r}"
        n = re.fullmatch(r"(\d+)(?: \(canonid's\))?", n_init)
        assert n, f"unreadable n_init {n_init!r}"
        if name == "bouc-wen":
            files = {"train": [m.group(1)], "test": [m.group(2), m.group(3)]}
        else:
            levels = [int(x) for x in m.groups()]
            files = {
                "train": [f"F16Data_FullMSine_Level{k}.mat" for k in levels[:4]],
                "test": [f"F16Data_FullMSine_Level{k}_Validation.mat" for k in levels[4:]],
            }
        dt = None if sampling == "`Fs` from the file (400 Hz)" else _sampling(sampling)
        out[name] = {"n_init": int(n.group(1)), "units": units, "dt": dt, "files": files}
    return out


def _check_added(text: str) -> None:
    protocol = _added_protocol(text)
    assert set(protocol) == set(ADDED.values())
    for name, stated in protocol.items():
        bench, expected = BENCHMARKS[name], EXPECTED[name]
        assert stated["n_init"] == bench.n_init == expected["n_init"], name
        assert stated["units"] == bench.score_units == expected["score"][0], name
        assert stated["dt"] is None or stated["dt"] == pytest.approx(expected["dt"], rel=1e-12)
        # the records each split reads, in order: the registry's files and the tests' EXPECTED
        assert stated["files"]["train"] == [part[0] for part in expected["train"]], name
        assert stated["files"]["test"] == [part[1] for part in expected["test"]], name
        assert bench.baselines == (), f"{name}: a published figure needs a table and a source"


def test_the_added_benchmarks_are_the_docs_protocol_table():
    _check_added(DOCS.read_text(encoding="utf-8"))


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("| 1/750 s |", "| 1/700 s |"),
        ("levels 1, 3, 5, 7", "levels 1, 3, 5, 6"),
        ("| 50 (canonid's) |", "| 40 (canonid's) |"),
        ("| m/s² |", "| g |"),
    ],
)
def test_the_added_protocol_table_refuses_a_changed_fact(old, new):
    text = DOCS.read_text(encoding="utf-8")
    assert old in text
    with pytest.raises(AssertionError):
        _check_added(text.replace(old, new))


@pytest.mark.parametrize("path", _texts())
def test_every_published_figure_is_entered_as_printed_with_its_source(path):
    _check_figures(_read(path))


@pytest.mark.parametrize("path", _texts())
def test_the_best_published_figure_of_every_test_part_is_marked(path):
    _check_best(_read(path))


@pytest.mark.parametrize(
    ("old", "new", "check"),
    [
        pytest.param("| GRU | 1.49 |", "| GRU | 1.490 |", _check_figures, id="a-digit-more"),
        pytest.param("| 0.224 | 0.384 |", "| 0.224 |", _check_figures, id="a-cell-less"),
        pytest.param("| 0.396 |", "| 0.39 6 |", _check_figures, id="an-unreadable-cell"),
        pytest.param("(Forgione and Piga, 2021a)", "(Piga, 2021a)", _check_figures, id="source"),
        pytest.param("0.096 /\n0.074.", "0.096 /\n0.070.", _check_best, id="bar-to-beat"),
        pytest.param("4 → **10**", "4 → **4**", _check_protocol, id="n_init"),
        pytest.param("train `[:400]`", "train `[:300]`", _check_protocol, id="ced-split"),
        pytest.param("first 75 %", "first 70 %", _check_protocol, id="silverbox-split"),
        pytest.param("last 78,800 test", "last 78,000 test", _check_protocol, id="wh-split"),
        pytest.param("| 1/610.35 s |", "| 1/610 s |", _check_protocol, id="sampling"),
    ],
)
def test_a_changed_number_or_row_fails_the_check(old, new, check):
    assert old in PUBLISHED
    check(PUBLISHED)
    with pytest.raises(AssertionError):
        check(PUBLISHED.replace(old, new))


def test_one_source_and_one_note_per_method_and_benchmark():
    for bench in BENCHMARKS.values():
        by_method = {(b.method, b.source, b.note) for b in bench.baselines}
        assert len(by_method) == len({b.method for b in bench.baselines}), bench.name


@pytest.mark.parametrize("name", list(BENCHMARKS))
def test_the_docs_show_each_benchmarks_published_results_from_the_registry(name):
    """docs/benchmarks.md holds each table between markers; it must be what the registry makes."""
    page = DOCS.read_text(encoding="utf-8")
    m = re.search(
        rf"<!-- BEGIN baselines {name} -->\n(.*?)\n<!-- END baselines {name} -->", page, flags=re.S
    )
    assert m, f"{DOCS}: no '<!-- BEGIN baselines {name} -->' … '<!-- END … -->' section"
    expected = baselines_markdown(name)
    assert m.group(1).strip() == expected, (
        f"{DOCS}: the {name} table differs from the registry's; replace the section with:\n"
        f"{expected}"
    )


def _printed(name: str, scores: list[float], baselines: list | None = None) -> str:
    """What ``canonid benchmark NAME`` prints for a run that scored ``scores`` on the parts."""
    bench = BENCHMARKS[name]
    parts = [
        PartScore(test, rmse, bench.score_units, bench.n_init, 100)
        for test, rmse in zip(bench.test_parts, scores, strict=True)
    ]
    report = BenchmarkReport(
        benchmark=name,
        title=bench.title,
        definition="nonlinear_benchmarks 1.0.1",
        files=[],
        model="mlp",
        window=10,
        profile="quick",
        validation="the last 20 %",
        scores=parts,
        baselines=list(bench.baselines) if baselines is None else baselines,
        rule="",
    )
    return report_table(report)


@pytest.mark.parametrize("path", _texts())
@pytest.mark.parametrize("name", [n for n in BENCHMARKS if n not in ADDED.values()])
def test_the_printed_table_shows_each_published_figure_as_published(path, name):
    """One row per method, one column per test part: every figure with the digits of
    BASELINES.md, the lowest per part marked, canonid's row in the same units, every source
    numbered once."""
    published = {(t, m): f for (b, t, m), (f, _) in _figures(_read(path)).items() if b == name}
    bench = BENCHMARKS[name]
    ours = [0.5 + i / 8 for i in range(len(bench.test_parts))]
    head, header, canonid, *rest = _printed(name, ours).splitlines()
    assert f"simulation RMSE [{bench.score_units}]" in head and f"n_init = {bench.n_init}" in head
    assert re.split(r" {2,}", header) == ["method", *bench.test_parts, "source"]
    assert re.split(r" {2,}", canonid) == [
        "canonid (mlp, ℓ = 10)",
        *(f"{v:.3f}" for v in ours),
        "this run",
    ]
    rows = [re.split(r" {2,}", line) for line in rest[: len({m for _, m in published})]]
    assert len({r[0] for r in rows}) == len(rows)  # one row per method
    printed = {
        (test, row[0]): cell
        for row in rows
        for test, cell in zip(bench.test_parts, row[1:-1], strict=True)
        if cell != "-"
    }
    assert {k: c.rstrip("*") for k, c in printed.items()} == published
    lowest: dict[str, str] = {}
    for (test, _), figure in published.items():
        lowest[test] = min(lowest.get(test, figure), figure, key=float)
    assert {t: c[:-1] for (t, _), c in printed.items() if c.endswith("*")} == lowest
    tail = rest[len(rows) :]
    sources = sorted({b.source for b in bench.baselines})
    assert sorted(line.split("] ", 1)[1] for line in tail if line.startswith("[")) == sources
    assert tail[0].startswith("* ") and "Standard benchmarks" in tail[-1]


def test_a_benchmark_without_published_figures_says_so():
    table = _printed("emps", [1.0], baselines=[]).splitlines()
    assert [re.split(r" {2,}", line)[0] for line in table[1:3]] == [
        "method",
        "canonid (mlp, ℓ = 10)",
    ]
    assert table[3:] == ["published baselines: none entered for this benchmark"]


@pytest.mark.parametrize("name", sorted(ADDED.values()))
def test_the_added_benchmarks_print_their_scores_alone(name):
    """Bouc–Wen and the F-16: one column per official part, canonid's row, and the line that
    says no published figure is entered; a score below 0.1 keeps three significant digits."""
    parts = BENCHMARKS[name].test_parts
    head, header, canonid, *rest = _printed(name, [0.0123] * len(parts)).splitlines()
    assert f"n_init = {BENCHMARKS[name].n_init}" in head
    assert re.split(r" {2,}", header) == ["method", *parts, "source"]
    assert re.split(r" {2,}", canonid)[1:-1] == ["0.0123"] * len(parts)
    assert rest == ["published baselines: none entered for this benchmark"]
