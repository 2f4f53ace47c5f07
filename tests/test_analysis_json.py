"""``analysis.json`` read back: Estimate.from_dict, AnalysisReport.from_json, learned checks."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from canonid.analysis.estimate import Budget, Estimate
from canonid.analysis.linear import canonical_regressor
from canonid.analysis.report import AnalysisReport, analyze
from canonid.kernel.dataset import Trajectory
from canonid.kernel.errors import DataError, SetError
from canonid.kernel.io import jsonable
from canonid.models.registry import get_system
from canonid.models.sets import Box


@settings(max_examples=60, deadline=None)
@given(
    value=st.one_of(st.floats(0, 1e300), st.just(math.inf)),
    kind=st.sampled_from(["lower", "upper", "estimate"]),
    quantity=st.sampled_from(["gamma_f", "gamma_h", "alpha"]),
    window=st.one_of(st.none(), st.integers(1, 20)),
    lo=st.floats(-10, 0),
    width=st.floats(0, 10),
)
def test_estimate_survives_its_json_record(value, kind, quantity, window, lo, width):
    estimate = Estimate(
        quantity=quantity,
        value=value,
        kind=kind,
        sets={"X": Box([lo, lo], [lo + width, lo + 2 * width])},
        method="sampled",
        window=window,
        budget=Budget(boxes=10).to_dict(),
        seconds=0.25,
        details={"boxes": 3},
    )
    record = json.loads(json.dumps(estimate.to_dict()))  # infinity travels as null
    back = Estimate.from_dict(record)
    assert back.value == value and back.kind == kind and back.window == window
    assert back.to_dict() == estimate.to_dict()


@pytest.fixture(scope="module")
def linear_report(tmp_path_factory):
    report = analyze(
        get_system("linear"),
        [2, 3],
        trials=10,
        budget=Budget(boxes=300, samples=256, starts=2),
        starts=2,
    )
    path = report.write_json(tmp_path_factory.mktemp("analysis") / "analysis.json")
    return report, path


def test_report_survives_its_json(linear_report):
    report, path = linear_report
    back = AnalysisReport.from_json(path)
    assert jsonable(back.to_dict()) == jsonable(report.to_dict())
    assert back.table() == report.table()
    assert [r.window for r in back.results] == [2, 3]
    assert back.constants(3).to_dict() == report.constants(3).to_dict()


def test_report_json_errors_name_the_file(tmp_path):
    path = tmp_path / "analysis.json"
    path.write_text(json.dumps({"system": {"name": "linear"}}))
    with pytest.raises(DataError, match=str(path)):
        AnalysisReport.from_json(path)


def test_constants_are_the_certified_bounds_of_the_window(linear_report):
    report, _ = linear_report
    constants = report.constants(2)
    assert (constants.gamma_f.kind, constants.alpha.kind) == ("upper", "lower")
    assert constants.gamma_h is not None and constants.gamma_h.kind == "upper"
    with pytest.raises(SetError, match="ℓ = 7"):
        report.constants(7)


class _Exact:
    """The exact canonical map of the linear system, as ``Model.export()`` presents a model."""

    def __init__(self, window: int) -> None:
        self.window = window
        self.H = canonical_regressor(get_system("linear"), window)


def _trajectories(seed: int, count: int) -> list[Trajectory]:
    system, rng = get_system("linear"), np.random.default_rng(seed)
    out = []
    for _ in range(count):
        u = rng.uniform(-0.05, 0.05, size=(40, 1))
        sim = system.simulate(rng.uniform(-0.3, 0.3, size=2), u)
        w = rng.uniform(system.W.lo, system.W.hi, size=sim.y.shape)
        out.append(Trajectory(u=u, y=sim.y + w, y_clean=sim.y, x=sim.x))
    return out


def test_learned_checks_of_the_exact_map_stay_within_the_level(linear_report):
    report, path = linear_report
    train, test = _trajectories(0, 3), _trajectories(1, 2)
    models = [_Exact(3), _Exact(2), _Exact(3)]
    checks = AnalysisReport.from_json(Path(path)).learned_checks(models, train, test)
    assert [r.window for r in checks.residuals] == [3, 2, 3]
    for r in checks.residuals:
        assert r.rows == 2 * (40 - r.window) and r.within == r.rows
    assert [p.window for p in checks.probes] == [2, 3]  # one probe per window
    without_states = [Trajectory(u=t.u, y=t.y, y_clean=t.y_clean) for t in test]
    assert report.learned_checks(models, train, without_states).probes == []


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ({1: (np.float32(0.5), np.int64(3))}, {"1": [0.5, 3]}),
        ([math.nan, -math.inf, np.float64(2.0)], [None, None, 2.0]),
        (np.array([[1, 2], [3, 4]]), [[1, 2], [3, 4]]),
        ({"ok": np.bool_(True), "path": Path("a/b")}, {"ok": True, "path": "a/b"}),
    ],
)
def test_jsonable_makes_values_json_ready(value, expected):
    out = jsonable(value)
    assert out == expected
    assert json.loads(json.dumps(out, allow_nan=False)) == out
