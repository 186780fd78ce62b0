"""SB3's SAC and PPO learn from oracle preferences, far beyond random play, on the line
task (thresholds measured over 12 seeds: tests/learning_thresholds.md)."""

from __future__ import annotations

import numpy as np
import pytest

from support.sb3_learning import learned_return

SEEDS = (0, 1, 2)
RANDOM = -32.8  # mean true return of uniformly random actions, 120 episodes


@pytest.mark.parametrize(("agent", "threshold"), [("SAC", -28.0), ("PPO", -27.0)])
def test_an_sb3_agent_learns_from_oracle_preferences_beyond_random(agent, threshold):
    mean = float(np.mean([learned_return(agent, seed) for seed in SEEDS]))
    assert mean > threshold > RANDOM
