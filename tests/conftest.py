"""Shared fixtures. Numerics are strict: float64 everywhere; numpy errors (not underflow) raise."""

from __future__ import annotations

import os

import numpy as np
import pytest

# Tests run on 2 cores next to other jobs: keep the math libraries to one thread each.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

from canonid.models.registry import get_system, system_names


@pytest.fixture(autouse=True)
def _strict_numpy():
    old = np.seterr(all="raise", under="ignore")  # underflow to 0 is benign
    try:
        yield
    finally:
        np.seterr(**old)


@pytest.fixture(params=system_names())
def system(request):
    """Every registered system, built with its default parameters."""
    return get_system(request.param)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
