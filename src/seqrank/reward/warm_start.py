"""RIME's warm start (Cheng et al., ICML 2024, Section 4.2): during unsupervised
pre-training the reward model is fitted to the intrinsic reward the agent learns from,
so that the first feedback session starts from a reward the policy already follows
(the transition from pre-training to preference learning is smoother).

From their `train_RIME.py`: after each pre-training step, 5 Adam steps of the summed
members' mean squared error to the state-entropy reward of fresh replay batches, the
reward standardised by its running statistics and scaled into [-1, 1] (the ensemble's
tanh output). Ours scales by the batch's largest magnitude; theirs by the largest of
the running statistics'.
"""

from __future__ import annotations

import torch

from seqrank.reward.entropy import RunningMeanStd
from seqrank.reward.model import RewardModel

UPDATES_PER_STEP = 5  # their `for _ in range(5)` after each pre-training step


def warm_start_target(distance: torch.Tensor, stats: RunningMeanStd) -> torch.Tensor:
    """The k-NN distances (B, 1) standardised by `stats` and scaled into [-1, 1]."""
    standard = (distance - stats.mean) / max(stats.std, 1e-8)
    return standard / standard.abs().max().clamp_min(1e-8)


def fit_intrinsic(
    model: RewardModel, obs: torch.Tensor, action: torch.Tensor, target: torch.Tensor
) -> torch.Tensor:
    """One Adam step of every member towards `target` (B, 1); returns the members' mean
    loss, on the device (reading it back would wait for the device at every step)."""
    predicted = model.net(torch.cat([obs, action], dim=-1))  # (members, B, 1)
    loss = (predicted - target).pow(2).mean((1, 2)).sum()
    model.optimizer.zero_grad(set_to_none=True)
    loss.backward()
    model.optimizer.step()
    return loss.detach() / model.members
