"""The rewards IQL trains on, scaled as IQL (returns) and LiRE (unit) scale them: against
numbers worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from seqrank.offline.rewards import resolve_scale, scale_rewards
from seqrank.offline.settings import RewardScale

# three episodes: returns 6, 0 and 5
REWARDS = np.array([1.0, 2.0, 3.0, 0.0, 0.0, 5.0], np.float32)
STARTS = np.array([0, 3, 5])


def test_returns_scaling_spreads_the_episode_returns_over_1000():
    scaled = scale_rewards(REWARDS, STARTS, RewardScale.RETURNS)
    np.testing.assert_allclose(scaled, REWARDS * 1000 / (6 - 0), rtol=1e-6)
    returns = np.add.reduceat(scaled.astype(np.float64), STARTS)
    assert returns.max() - returns.min() == pytest.approx(1000.0)


def test_unit_scaling_maps_the_rewards_onto_zero_to_one():
    scaled = scale_rewards(REWARDS - 2, STARTS, RewardScale.UNIT)  # min -2, max 3
    np.testing.assert_allclose(scaled, [0.2, 0.4, 0.6, 0.0, 0.0, 1.0], rtol=1e-6)


def test_no_spread_leaves_the_rewards_as_they_are():
    flat = np.ones(6, np.float32)
    for scale in (RewardScale.RETURNS, RewardScale.UNIT, RewardScale.NONE):
        np.testing.assert_array_equal(scale_rewards(flat, np.array([0, 2, 4]), scale), flat)


def test_auto_is_lires_unit_on_meta_world_and_iqls_returns_elsewhere():
    assert resolve_scale("auto", "metaworld:button-press-topdown-v3") is RewardScale.UNIT
    assert resolve_scale("auto", "walker_walk") is RewardScale.RETURNS
    assert resolve_scale("auto", "gym:Pendulum-v1") is RewardScale.RETURNS
    assert resolve_scale("none", "metaworld:button-press-topdown-v3") is RewardScale.NONE
