"""What DQN is given: keywords only (seven numbers in a row cannot be told apart), and
read from the run's config by name."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import pytest
import torch

from seqrank.agents.dqn import DQNSettings, EpsilonSchedule
from seqrank.config import TrainConfig
from seqrank.training.agent_factory import make_dqn


def test_dqn_settings_take_keywords_only():
    with pytest.raises(TypeError):
        DQNSettings(32, 2, 1e-2, 0.0, 1.0, 1, EpsilonSchedule())  # type: ignore[misc]


def test_dqn_settings_are_read_from_the_run_config_by_name():
    config = replace(
        TrainConfig(), hidden=24, layers=3, critic_lr=2e-3, discount=0.9, tau=0.01,
        target_update_every=4, seed_steps=77,
    )  # fmt: skip
    settings = make_dqn(
        config, SimpleNamespace(obs_dim=5, act_dim=3, discrete=True), torch.device("cpu")
    ).settings
    assert settings == DQNSettings(
        hidden=24, layers=3, lr=2e-3, discount=0.9, tau=0.01, target_update_every=4,
        epsilon=EpsilonSchedule(random_steps=77),
    )  # fmt: skip
