"""A step's action and learned reward on a CPU are computed for one row in numpy (torch's
cost per call dominated there): they must be the batched torch networks' numbers."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_sac_paths import ACT, CPU, OBS, SETTINGS

from seqrank.agents.sac import SAC
from seqrank.agents.sac.networks import squashed_gaussian
from seqrank.buffer import ReplayBuffer
from seqrank.reward.model import RewardModel


def _spread_log_std(agent: SAC) -> None:
    """Weights large enough that the raw log-std reaches both ends of its squashing."""
    with torch.no_grad():
        for parameter in agent.actor.parameters():
            parameter.mul_(4.0)


@pytest.mark.parametrize("layers", [1, 2, 3])
def test_a_cpu_step_action_is_the_batched_policys(layers):
    from dataclasses import replace

    torch.manual_seed(layers)
    agent = SAC(OBS, ACT, replace(SETTINGS, layers=layers), CPU)
    _spread_log_std(agent)
    observations = torch.randn((20, OBS), generator=torch.Generator().manual_seed(1)) * 3
    for deterministic in (False, True):
        generator, mirror = torch.Generator().manual_seed(7), torch.Generator().manual_seed(7)
        acted = np.stack([agent.act(o.numpy(), deterministic, generator) for o in observations])
        noise = torch.cat([torch.randn((1, ACT), generator=mirror) for _ in observations])
        with torch.no_grad():
            sampled, _, mean = squashed_gaussian(agent.actor.net(observations), noise)
        expected = (mean if deterministic else sampled).numpy()
        assert acted.dtype == np.float32 and acted.shape == (20, ACT)
        # float32 sums in another order: large weights make the rounding reach 1e-5
        np.testing.assert_allclose(acted, expected, rtol=1e-4, atol=1e-5)
        assert not deterministic or np.abs(acted - sampled.numpy()).max() > 1e-3


def test_a_cpu_step_action_follows_the_weights_as_they_train():
    torch.manual_seed(0)
    agent = SAC(OBS, ACT, SETTINGS, CPU)
    obs = np.ones(OBS, np.float32)
    before = agent.act(obs, True, torch.Generator())
    with torch.no_grad():  # in place, as the optimiser and a checkpoint load write them
        agent.actor.net[0].bias.add_(1.0)
    after = agent.act(obs, True, torch.Generator())
    with torch.no_grad():
        _, _, expected = squashed_gaussian(agent.actor.net(torch.ones(1, OBS)), torch.zeros(1, ACT))
    assert not np.allclose(before, after)
    np.testing.assert_allclose(after, expected[0].numpy(), rtol=1e-5, atol=1e-6)


def _model(layers: int) -> RewardModel:
    torch.manual_seed(0)
    model = RewardModel(3, OBS + ACT, 32, layers, 3e-4, CPU)
    with torch.no_grad():  # both signs before every activation, and outputs off tanh's middle
        for parameter in model.net.parameters():
            parameter.mul_(3.0)
    return model


@pytest.mark.parametrize("layers", [1, 3])
def test_a_cpu_step_reward_is_the_ensembles_mean(layers):
    model = _model(layers)
    obs = torch.randn((30, OBS), generator=torch.Generator().manual_seed(2))
    action = torch.rand((30, ACT), generator=torch.Generator().manual_seed(3)) * 2 - 1
    with torch.no_grad():
        batched = model.net(torch.cat([obs, action], -1)).mean(0)
        rows = torch.cat([model.reward(obs[i : i + 1], action[i : i + 1]) for i in range(30)])
    assert rows.shape == (30, 1) and batched.abs().max() > 0.3
    torch.testing.assert_close(rows, batched, rtol=1e-5, atol=1e-6)
    # with gradients on (MRN's meta step), one row still goes through the torch networks
    one = model.reward(obs[:1], action[:1])
    assert one.requires_grad and one.shape == (1, 1)


def test_the_stored_reward_of_a_step_is_what_relabelling_gives():
    model = _model(3)
    buffer = ReplayBuffer(50, OBS, ACT, CPU)
    generator = np.random.default_rng(4)
    for i in range(40):
        obs, next_obs = generator.standard_normal((2, OBS)).astype(np.float32)
        action = generator.uniform(-1, 1, ACT).astype(np.float32)
        buffer.add_transition(obs, action, 0.0, next_obs, i % 9 == 8, model.reward)
    stored = buffer.reward[:40].clone()
    buffer.relabel(model.reward)
    assert stored.abs().max() > 0.3
    torch.testing.assert_close(stored, buffer.reward[:40], rtol=1e-5, atol=1e-6)
