"""Evaluation against closed forms: which samples each score uses, and the formulas."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from canonid.kernel.errors import ShapeError
from canonid.learning import evaluate


class EchoModel:
    """A stand-in for a trained model on the system y_t = u_t: it predicts u_t plus the error of
    the last burn-in sample (y_{ℓ−1} − u_{ℓ−1}) plus a constant ``offset``."""

    name, n_u, n_y = "echo", 1, 1

    def __init__(self, window: int, offset: float = 0.0) -> None:
        self.window, self.offset = window, offset

    def predict(self, u: np.ndarray, y_burn_in: np.ndarray) -> np.ndarray:
        carry = y_burn_in[:, -1:, :] - u[:, self.window - 1 : self.window, :]
        return u[:, self.window :, :] + carry + self.offset


@pytest.fixture
def records(rng):
    out = []
    for T in (70, 64, 30):  # the last is too short for a 50-step rollout
        u = rng.normal(size=(T, 1))
        out.append(SimpleNamespace(u=u, y=u + rng.uniform(-0.1, 0.1, size=(T, 1)), y_clean=u))
    return out


def test_rollout_metric_uses_every_start_with_the_measured_burn_in(records):
    ell, H, stride = 3, 50, 4
    ev = evaluate(EchoModel(ell), records, horizon=H, stride=stride, n_init=10)
    expected_sq, count = [], 0
    for r in records:
        w = (r.y - r.y_clean)[:, 0]
        for s in range(0, len(w) - ell - H + 1, stride):
            # prediction = u + w[s+ℓ−1]; against y: error w[s+ℓ−1] − w[t]; against y_clean: w[s+ℓ−1]
            expected_sq.append((w[s + ell - 1] - w[s + ell : s + ell + H]) ** 2)
            count += 1
    assert ev.n_rollouts == count == len(range(0, 70 - 53 + 1, 4)) + len(range(0, 64 - 53 + 1, 4))
    assert ev.measured.rollout_mse == pytest.approx(np.mean(expected_sq), rel=1e-12)
    assert ev.clean is not None
    clean_sq = [
        (r.y - r.y_clean)[s + ell - 1, 0] ** 2
        for r in records
        for s in range(0, r.u.shape[0] - ell - H + 1, stride)
    ]
    assert ev.clean.rollout_mse == pytest.approx(np.mean(clean_sq), rel=1e-12)
    # the k-step curve of the clean target: every step carries the same burn-in error
    sd = np.concatenate([r.y_clean for r in records]).std()
    np.testing.assert_allclose(ev.clean.kstep_nrmse, np.sqrt(np.mean(clean_sq)) / sd, rtol=1e-12)
    assert len(ev.clean.kstep_nrmse) == H


def test_per_record_rollout_mse_is_each_records_own_score(records):
    ell, H, stride = 3, 50, 4
    ev = evaluate(EchoModel(ell), records, horizon=H, stride=stride, n_init=10)
    assert ev.clean is not None
    for scores, target in ((ev.measured, "y"), (ev.clean, "y_clean")):
        per = scores.rollout_mse_per_record
        assert per[2] is None  # 30 samples: too short for one 53-sample rollout
        for i in (0, 1):
            alone = evaluate(EchoModel(ell), [records[i]], horizon=H, stride=stride, n_init=10)
            own = alone.measured if target == "y" else alone.clean
            assert own is not None and per[i] == pytest.approx(own.rollout_mse, rel=1e-12)
        # the overall score is the rollout-count-weighted mean of the records'
        counts = [len(range(0, len(r.u) - ell - H + 1, stride)) for r in records[:2]]
        weighted = (counts[0] * per[0] + counts[1] * per[1]) / sum(counts)
        assert scores.rollout_mse == pytest.approx(weighted, rel=1e-12)


def test_simulation_scores_skip_n_init_and_burn_in_just_before_it(records):
    ell, n_init = 3, 20
    ev = evaluate(EchoModel(ell), records, horizon=5, n_init=n_init)
    assert ev.n_records == 3 and ev.n_scored_samples == (70 - 20) + (64 - 20) + (30 - 20)
    carried = np.concatenate(
        [np.full(len(r.u) - n_init, (r.y - r.y_clean)[n_init - 1, 0]) for r in records]
    )
    assert ev.clean is not None
    assert ev.clean.rmse == pytest.approx(np.sqrt(np.mean(carried**2)), rel=1e-12)


def test_offset_gives_the_closed_form_rmse_nrmse_and_fit():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(80, 1))
    clean = [SimpleNamespace(u=u, y=u, y_clean=u)]
    c, ell, n_init = 0.25, 4, 50
    ev = evaluate(EchoModel(ell, offset=c), clean, horizon=10, n_init=n_init)
    scored = u[n_init:, 0]
    for scores in (ev.measured, ev.clean):
        assert scores is not None
        assert scores.rollout_mse == pytest.approx(c**2)
        assert scores.rmse == pytest.approx(c)
        assert scores.nrmse == pytest.approx(c / scored.std())
        fit = 100 * (1 - c * np.sqrt(len(scored)) / np.linalg.norm(scored - scored.mean()))
        assert scores.fit_percent == pytest.approx(fit)
    perfect = evaluate(EchoModel(ell), clean, horizon=10)
    assert perfect.measured.rollout_mse == 0 and perfect.measured.fit_percent == 100


def test_json_names_its_targets_and_keys(records):
    body = evaluate(EchoModel(3), records, horizon=10, n_init=10).to_json()
    for key in ("rollout_mse", "rmse", "nrmse", "fit_percent"):
        assert key in body and f"{key}_per_output" in body and key in body["clean"]
    assert len(body["rollout_mse_per_record"]) == len(records)
    assert body["targets"]["top_level"].startswith("y (measured")
    assert body["rollout_horizon"] == 10 and body["window"] == 3
    no_clean = [SimpleNamespace(u=r.u, y=r.y) for r in records]
    assert evaluate(EchoModel(3), no_clean, horizon=10).to_json()["clean"] is None


def test_bad_requests(records):
    with pytest.raises(ShapeError, match="no test trajectory holds window"):
        evaluate(EchoModel(3), records, horizon=100)
    with pytest.raises(ShapeError, match="n_init = 2 must be at least the window"):
        evaluate(EchoModel(3), records, horizon=5, n_init=2)
    with pytest.raises(ShapeError, match="longer than n_init"):
        evaluate(EchoModel(3), records, horizon=5, n_init=70)


class BlowUpModel(EchoModel):
    """The echo model whose open-loop prediction overflows after ``after`` steps."""

    def __init__(self, window: int, after: int) -> None:
        super().__init__(window)
        self.after = after

    def predict(self, u: np.ndarray, y_burn_in: np.ndarray) -> np.ndarray:
        out = super().predict(u, y_burn_in)
        out[:, self.after :, :] = np.inf
        return out


def test_a_simulation_that_blows_up_is_written_null_and_flagged(records, capsys):
    """JSON has no inf or NaN: such scores are null, ``finite`` says so, and the table warns."""
    import json

    from canonid.scoring import metrics_table as table

    ell = 3
    fine = evaluate(EchoModel(ell), records, horizon=20, stride=5, n_init=10)
    assert fine.finite and fine.to_json()["finite"] is True
    # rollouts of 20 steps stay finite; the long simulation passes step 30 and overflows
    ev = evaluate(BlowUpModel(ell, after=30), records, horizon=20, stride=5, n_init=10)
    assert math.isfinite(ev.measured.rollout_mse) and not math.isfinite(ev.measured.rmse)
    body = ev.to_json()
    assert body["finite"] is False and body["rmse"] is None and body["clean"]["rmse"] is None
    assert body["rollout_mse"] == ev.measured.rollout_mse
    json.dumps(body, allow_nan=False)  # what atomic_write_json demands
    text = table({**body, "data": {"path": "test.csv", "split": "test"}})
    assert "not finite" in text and "blew up (inf or NaN)" in text


def test_a_mimo_table_has_one_row_per_output_under_each_target(rng):
    """Each output's scores are printed below the row over all outputs, with the values of
    metrics.json's ``*_per_output`` lists; a single-output table has no such rows."""
    from canonid.scoring import metrics_table as table

    class Echo2(EchoModel):
        name, n_u, n_y = "echo2", 2, 2

    u = rng.normal(size=(80, 2))
    noise = np.array([0.05, 0.4]) * rng.uniform(-1, 1, size=(80, 2))
    records = [SimpleNamespace(u=u, y=u + noise, y_clean=u)]
    ev = evaluate(Echo2(3), records, horizon=20, n_init=10, output_names=["left", "right"])
    body = {**ev.to_json(), "data": {"path": "d.npz", "split": "test"}}
    lines = table(body).splitlines()
    for target, scores in (("y (measured)", body), ("y_clean", body["clean"])):
        at = next(i for i, line in enumerate(lines) if line.startswith(target))
        for k, name in enumerate(["left", "right"]):
            cells = lines[at + 1 + k].split()
            assert cells[0] == name
            assert float(cells[4]) == pytest.approx(scores["fit_percent_per_output"][k], abs=0.006)
            assert float(cells[2]) == pytest.approx(scores["rmse_per_output"][k], rel=1e-3)
    per = body["fit_percent_per_output"]
    assert per[0] > per[1]  # the noisier output fits worse, and the table shows which
    single = evaluate(
        EchoModel(3),
        [SimpleNamespace(u=u[:, :1], y=u[:, :1], y_clean=None)],
        horizon=20,
        n_init=10,
    )
    assert len(table({**single.to_json(), "data": {"path": "d", "split": "t"}}).splitlines()) == 3
