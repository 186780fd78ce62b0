"""MRN on the flat update (the fast path on a CPU) against the reference path: the meta
reward step differentiates through one functional step of the critic, which on the flat
path is a module whose parameters view flat buffers; the agent's update after it is the
flat update. Both must give the reference's numbers within float tolerance (the stacked
critic sums its products in another order)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from seqrank.agents.mrn import MetaRewardUpdate, MetaSettings, PairBatch
from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.agents.sac.critics import canonical_weights
from seqrank.buffer import ReplayBuffer
from seqrank.reward.model import RewardModel

CPU = torch.device("cpu")
OBS, ACT, ROWS, PAIRS = 3, 2, 32, 16
SETTINGS = SACSettings(
    hidden=16,
    layers=2,
    actor_lr=1e-3,
    critic_lr=1e-2,
    alpha_lr=1e-4,
    init_temperature=0.1,
    discount=0.99,
    tau=0.005,
    target_update_every=1,
)


def filled_replay() -> ReplayBuffer:
    replay = ReplayBuffer(capacity=200, obs_dim=OBS, act_dim=ACT, device=CPU)
    rng = np.random.default_rng(0)
    for i in range(200):
        obs, next_obs = rng.normal(size=OBS), rng.normal(size=OBS)
        action = rng.uniform(-1, 1, size=ACT)
        replay.add(obs, action, 0.0, float(rng.normal()), next_obs, i % 50 == 49)
    return replay


def recent_pairs() -> PairBatch:
    generator = torch.Generator().manual_seed(3)
    first_obs, second_obs = (torch.randn(PAIRS, OBS, generator=generator) for _ in range(2))
    first_action, second_action = (
        torch.rand(PAIRS, ACT, generator=generator) * 2 - 1 for _ in range(2)
    )
    labels = (first_obs[:, 0] > second_obs[:, 0]).float()
    labels[:2] = 0.5
    return PairBatch(first_obs, first_action, second_obs, second_action, labels)


def run_mrn(start: SAC, execution: Execution) -> tuple[SAC, RewardModel, list[float], int]:
    """Three steps of MRN's update (meta steps at 0 and 2) from `start`'s weights."""
    agent = SAC(OBS, ACT, SETTINGS, CPU, execution)
    agent.load_state_dict(start.state_dict())
    torch.manual_seed(1)
    model = RewardModel(3, OBS + ACT, 16, 2, 1e-2, CPU)
    losses: list[float] = []
    relabelled = []
    update = MetaRewardUpdate(
        agent,
        model,
        filled_replay(),
        MetaSettings(batch=ROWS, every=2, loss_weight=0.1),
        recent_pairs,
        relabel=lambda: relabelled.append(True),
        generator=torch.Generator().manual_seed(5),
        record=lambda name, value: losses.append(value),
    )
    for step in range(3):
        update(step, feedback_open=True)
    return agent, model, losses, len(relabelled)


def test_mrn_on_the_flat_update_follows_the_reference_path():
    torch.manual_seed(0)
    start = SAC(OBS, ACT, SETTINGS, CPU)
    reference, reference_model, reference_losses, _ = run_mrn(start, Execution())
    flat, flat_model, flat_losses, relabelled = run_mrn(start, Execution.fast(CPU, "fp32"))
    assert flat.execution.flat and relabelled == 2 and len(flat_losses) == 2
    assert flat_losses == pytest.approx(reference_losses, rel=1e-5)
    reward_weights = zip(flat_model.net.parameters(), reference_model.net.parameters(), strict=True)
    for ours, theirs in reward_weights:
        torch.testing.assert_close(ours, theirs, rtol=1e-4, atol=1e-6)
    for part in ("critic", "critic_target"):
        ours, theirs = (canonical_weights(getattr(a, part)) for a in (flat, reference))
        for name, value in theirs.items():
            torch.testing.assert_close(ours[name], value, rtol=1e-4, atol=1e-6)
    for ours, theirs in zip(flat.actor.parameters(), reference.actor.parameters(), strict=True):
        torch.testing.assert_close(ours, theirs, rtol=1e-4, atol=1e-6)
    assert all(p.grad is None for p in flat.critic.parameters())  # the meta step leaves none
    assert flat.updates == reference.updates == 3
    torch.manual_seed(1)
    untrained = RewardModel(3, OBS + ACT, 16, 2, 1e-2, CPU)
    moved = zip(flat_model.net.parameters(), untrained.net.parameters(), strict=True)
    assert any(not torch.equal(ours, start) for ours, start in moved)  # the meta steps took
