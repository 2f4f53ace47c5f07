"""deepSI's SUBNET with its defaults, trained on a canonid dataset's training and validation
parts: the one recipe the benchmark scripts that set deepSI beside canonid's defaults share.

``deepSI.SUBNET(n_u, n_y, norm)`` (state dimension 10, encoder windows na = nb = 20, residual
MLPs) trained by ``deepSI.fit`` (rollouts T = 50, batch 256, Adam at 1e-3, validation every 250
iterations by a simulation of the validation part, the best model kept) for a given number of
iterations (``deepSI.fit`` has no default for it), in this process with one torch thread and
torch's seed (0 unless given); deepSI's checkpoint file goes to a temporary folder, not ``$HOME``.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from contextlib import redirect_stdout
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Subnet:
    """The trained SUBNET (best on validation) behind canonid's ``predict`` and where it was
    best: ``at`` iterations of ``iterations``."""

    model: Any  # bench_deepsi.SubnetModel
    at: int
    iterations: int


def fit_subnet(train: Sequence[Any], val: Sequence[Any], iterations: int, seed: int = 0) -> Subnet:
    """Train deepSI's SUBNET with its defaults on the first training and validation record
    (canonid :class:`~canonid.kernel.dataset.Trajectory` objects), torch seeded by ``seed``."""
    os.environ.setdefault("TQDM_DISABLE", "1")  # deepSI draws a progress bar per fit
    import deepSI
    import deepSI.fitting
    import torch
    from bench_deepsi import SubnetModel
    from nonlinear_benchmarks import Input_output_data

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    records = [Input_output_data(u=t.u, y=t.y) for t in (train[0], val[0])]
    n_u, n_y, norm = deepSI.get_nu_ny_and_auto_norm(records[0])
    net = deepSI.SUBNET(n_u, n_y, norm)
    with tempfile.TemporaryDirectory() as tmp, open(os.devnull, "w") as quiet:
        deepSI.fitting.get_checkpoint_dir = lambda: tmp  # its checkpoint file: not in $HOME
        with redirect_stdout(quiet):
            info = deepSI.fit(net, records[0], records[1], n_its=iterations)
    best = info["best_model"]
    at = int(np.argmin(np.asarray(info["NRMS_val"]))) * int(info["val_freq"])
    return Subnet(model=SubnetModel(best, best.na, n_u, n_y), at=at, iterations=iterations)
