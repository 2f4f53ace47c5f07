"""``device="auto"``: the measured rule, tested on the CPU by its inputs.

The rule (:func:`canonid.learning.training.auto_device`) reads the work of one rollout step;
``benchmarks/device/*.json`` holds the GPU run that measured where a GPU starts to pay off. The
rule must reproduce every verdict of that run (GPU against the fastest measured CPU thread
count, at each stack size and width), and the Device record's notes must quote the threshold
the code holds.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import torch

from canonid.kernel.errors import OptionError
from canonid.learning.nets import build_net
from canonid.learning.training import (
    AUTO_CUDA_WORK,
    auto_device,
    network_work,
    resolve_device,
)

ROOT = Path(__file__).resolve().parents[1]
MEASURED = sorted((ROOT / "benchmarks" / "device").glob("*.json"))


def verdicts(record: dict) -> list[tuple[int, str]]:
    """(work, faster device) for every stack the run trained on the GPU and on the CPU."""
    jobs = [j for j in record["jobs"] if not j["error"]]
    out = []
    for g in (j for j in jobs if j["device"] == "cuda"):
        cpu = [
            j["wall_s"]
            for j in jobs
            if j["device"] == "cpu" and j["hidden"] == g["hidden"] and j["k"] == g["k"]
        ]
        if cpu:
            out.append((g["work"], "cuda" if g["wall_s"] < min(cpu) else "cpu"))
    return out


@pytest.mark.parametrize("path", MEASURED, ids=[p.name for p in MEASURED])
def test_the_rule_reproduces_every_measured_verdict(path: Path) -> None:
    measured = verdicts(json.loads(path.read_text()))
    assert {device for _, device in measured} == {"cpu", "cuda"}  # the run saw both sides win
    for work, faster in measured:
        assert auto_device(work, cuda_available=True) == faster, (work, faster)


def test_without_cuda_auto_is_always_the_cpu() -> None:
    for work in (0, AUTO_CUDA_WORK - 1, AUTO_CUDA_WORK, 10**12):
        assert auto_device(work, cuda_available=False) == "cpu"
    assert auto_device(AUTO_CUDA_WORK, cuda_available=True) == "cuda"
    assert auto_device(AUTO_CUDA_WORK - 1, cuda_available=True) == "cpu"


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks a machine without CUDA")
def test_resolve_device_without_cuda() -> None:
    assert resolve_device("auto", work=10**12).type == "cpu"
    assert resolve_device("auto").type == "cpu"
    with pytest.raises(OptionError, match="CUDA is not available"):
        resolve_device("cuda")


def test_network_work_counts_weight_matrices_once_per_candidate_and_row() -> None:
    net = build_net("mlp", window=10, n_u=1, n_y=1, hidden=[256, 256, 256])
    # [z; u] is 10·(1+1)+1 = 21 wide: 21·256 + 256·256 + 256·256 + 256·1 weights
    weights = 21 * 256 + 2 * 256 * 256 + 256
    assert network_work(net, 32) == 32 * weights
    assert network_work(net, 32, candidates=8) == 8 * 32 * weights
    # the default model on the tank stays on the CPU (a GPU was slower for it)
    assert auto_device(network_work(net, 32), cuda_available=True) == "cpu"


def test_results_quote_the_threshold_the_code_holds() -> None:
    text = (ROOT / "benchmarks" / "records" / "device.md").read_text(encoding="utf-8")
    section = text.split("<!-- BEGIN Device -->", 1)[1].split("<!-- END Device -->", 1)[0]
    quoted = re.search(r"beat one CPU thread from \*\*([\d.]+) M\*\*", section)
    assert quoted, "benchmarks/records/device.md: no threshold sentence"
    assert float(quoted.group(1)) == round(AUTO_CUDA_WORK / 1e6, 1)
