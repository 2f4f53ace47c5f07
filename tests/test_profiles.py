"""Typed profiles: every profile builds, and a misspelt key at any level is an error naming it."""

from __future__ import annotations

import copy

import pytest

from canonid.learning.training import OptionError
from canonid.profiles import PROFILES, Profile, load_profile, profile_names


@pytest.mark.parametrize("name", profile_names())
def test_every_profile_builds(name):
    p = load_profile(name)
    assert p.name == name and p.train.epochs >= 1 and p.reduce.train.epochs >= 1
    assert p.reproduce is not None and p.reproduce.seeds >= 1


def _misspelt(path: tuple[str, ...], key: str) -> dict:
    data = copy.deepcopy(PROFILES["tiny"])
    node = data
    for part in path:
        node = node.setdefault(part, {})
    node[key] = 1
    return data


@pytest.mark.parametrize(
    ("path", "key", "where"),
    [
        ((), "reproduc", "profile 'tiny'"),
        (("train",), "epoch", "epoch"),
        (("reduce",), "encoder_hiden", "profile 'tiny', reduce"),
        (("reproduce",), "sytems", "profile 'tiny', reproduce"),
        (("reproduce", "evaluation"), "horizn", "reproduce.evaluation"),
        (("reproduce", "compression"), "rate", "reproduce.compression"),
        (("reproduce", "rollouts"), "windows", "reproduce.rollouts"),
        (("reproduce", "defaults"), "window", "reproduce.defaults"),
        (("reproduce", "train"), "lr_fnal", "reproduce.train"),
        (("reproduce", "train", "per_model", "mlp"), "epochz", "train.per_model.mlp"),
    ],
)
def test_a_misspelt_key_is_named(path, key, where):
    with pytest.raises(OptionError, match=key) as exc:
        Profile.from_dict("tiny", _misspelt(path, key))
    assert where in str(exc.value)
