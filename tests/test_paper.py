"""The paper's Table 1 as data: complete, in the paper's scale, with Ours (MLP)'s printed values."""

import pytest

from canonid.paper import PAPER_MODELS, PAPER_WINDOWS, TABLE1, table1_value


@pytest.mark.parametrize("system", sorted(TABLE1))
def test_every_cell_is_present(system):
    column = TABLE1[system]
    assert set(column.values) == set(PAPER_MODELS)
    assert all(len(v) == len(PAPER_WINDOWS) for v in column.values.values())


def test_values_in_physical_units():
    assert table1_value("tank", "mlp", 10) == pytest.approx(0.930e-4)
    assert table1_value("drone2d", "mlp", 30) == pytest.approx(3.13e-2)
    assert table1_value("quadrotor", "gru", 5) == pytest.approx(6.44e-2)
    assert table1_value("tank", "mlp", 7) is None
    assert table1_value("pendulum", "mlp", 10) is None
