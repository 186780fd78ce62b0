"""A reward learner's own settings are checked on that learner's runs only: a plain run of
short segments is not refused over SURF's crop, which it never uses."""

from __future__ import annotations

import pytest

import seqrank
from seqrank.errors import SettingError


def test_a_plain_run_takes_segments_shorter_than_surfs_default_crop():
    config = seqrank.make_config("walker_walk", segment_length=3)
    assert config.segment_length == 3 and config.surf_crop >= 3


def test_a_surf_run_keeps_a_step_of_every_crop():
    with pytest.raises(SettingError, match="surf_crop 5 must be smaller than segment_length 3"):
        seqrank.make_config("walker_walk", segment_length=3, reward_learner="surf")
    assert seqrank.make_config("walker_walk", segment_length=3, reward_learner="surf",
                               surf_crop=2).surf_crop == 2  # fmt: skip
