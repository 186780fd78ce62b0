"""Meta-Reward-Net's bi-level reward update (SPEC section 7).

The reward is judged by what it does to the critic: one plain-SGD step of a functional
copy of the critic on the critic loss under the learned reward, then the preference
cross-entropy of the updated critic's Q-values on recent labelled pairs is the outer loss
whose gradient flows back, through that step, into the reward parameters.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch.func import functional_call

from seqrank.agents.sac import SAC, critic_loss
from seqrank.buffer import Batch, BatchSource, ReplayBuffer
from seqrank.reward.model import RewardModel


@dataclass(frozen=True)
class PairBatch:
    """Labelled pairs scored by their segments' first state-action (obs, action)."""

    first_obs: torch.Tensor
    first_action: torch.Tensor
    second_obs: torch.Tensor
    second_action: torch.Tensor
    labels: torch.Tensor  # probability that `first` is preferred; 0.5 for equal


def outer_loss(
    agent: SAC,
    reward_model: RewardModel,
    batch: Batch,
    pairs: PairBatch,
    generator: torch.Generator,
    weight: float,
) -> torch.Tensor:
    """Outer loss after one functional SGD step of the critic (graph kept)."""
    target = reward_model.reward(batch.obs, batch.action) + agent.critic_target_value(
        batch, generator
    )
    params: dict[str, torch.Tensor] = dict(agent.critic.named_parameters())
    inner = critic_loss(functional_call(agent.critic, params, (batch.obs, batch.action)), target)
    grads = torch.autograd.grad(inner, list(params.values()), create_graph=True)
    lr = agent.settings.critic_lr
    stepped = {name: p - lr * g for (name, p), g in zip(params.items(), grads, strict=True)}
    q1_a, q2_a = functional_call(agent.critic, stepped, (pairs.first_obs, pairs.first_action))
    q1_b, q2_b = functional_call(agent.critic, stepped, (pairs.second_obs, pairs.second_action))
    labels = pairs.labels.unsqueeze(-1)
    cross_entropy = F.binary_cross_entropy_with_logits(q1_a - q1_b, labels) + (
        F.binary_cross_entropy_with_logits(q2_a - q2_b, labels)
    )
    return weight * cross_entropy


def meta_reward_step(
    agent: SAC,
    reward_model: RewardModel,
    batch: Batch,
    pairs: PairBatch,
    generator: torch.Generator,
    weight: float,
) -> float:
    """One outer step of the reward optimiser; leaves no gradient on the critic."""
    loss = outer_loss(agent, reward_model, batch, pairs, generator, weight)
    reward_model.optimizer.zero_grad(set_to_none=True)
    loss.backward()
    reward_model.optimizer.step()
    agent.critic.zero_grad(set_to_none=True)
    return float(loss.detach())


@dataclass(frozen=True)
class MetaSettings:
    batch: int
    every: int  # meta_update_frequency: steps between meta reward steps
    loss_weight: float


class MetaRewardUpdate:
    """MRN's agent update: every `every` steps while feedback is still being asked for,
    a meta reward step, then the agent's update on the batch under the new reward and a
    relabelled buffer; otherwise the agent's own update. Batches come from `hybrid`
    (QPA's hybrid replay) while feedback is asked for, when given, else from `replay`."""

    def __init__(
        self,
        agent: SAC,
        reward_model: RewardModel,
        replay: ReplayBuffer,
        settings: MetaSettings,
        recent_pairs: Callable[[], PairBatch | None],
        relabel: Callable[[], None],
        generator: torch.Generator,
        record: Callable[[str, float], None],
        hybrid: BatchSource | None = None,
    ):
        self.agent, self.reward_model, self.replay = agent, reward_model, replay
        self.settings, self.recent_pairs, self.relabel = settings, recent_pairs, relabel
        self.generator, self.record, self.hybrid = generator, record, hybrid

    def __call__(self, step: int, feedback_open: bool) -> None:
        due = feedback_open and step % self.settings.every == 0
        pairs = self.recent_pairs() if due else None
        source = self.hybrid if feedback_open and self.hybrid is not None else self.replay
        if pairs is None:
            self.agent.update_from(source, self.settings.batch, self.generator)
            return
        batch = source.sample(self.settings.batch, self.generator)
        loss = meta_reward_step(
            self.agent, self.reward_model, batch, pairs, self.generator, self.settings.loss_weight
        )
        self.record("meta_outer_loss", loss)
        with torch.no_grad():
            reward = self.reward_model.reward(batch.obs, batch.action)
        self.agent.update(
            Batch(batch.obs, batch.action, reward, batch.next_obs, batch.not_done), self.generator
        )
        self.relabel()
