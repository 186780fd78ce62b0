"""What the feedback does to an SB3 agent: PEBBLE's critic reset after the first session,
and, before it, the state-entropy reward of unsupervised pre-training in the batches an
off-policy agent samples (PEBBLE computes it per batch, against every stored state)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from torch import nn

from seqrank.reward.entropy import RunningMeanStd, intrinsic_reward
from seqrank.sb3.tables import ReplayTable


def is_off_policy(model: BaseAlgorithm) -> bool:
    return isinstance(model, OffPolicyAlgorithm)


def critic_parts(model: BaseAlgorithm) -> tuple[nn.Module, nn.Module, torch.optim.Optimizer]:
    """(critic, its target, the optimiser of the critic) of SAC / TD3 or DQN's Q-network."""
    if hasattr(model, "critic") and hasattr(model, "critic_target"):
        return model.critic, model.critic_target, model.critic.optimizer
    if hasattr(model, "q_net") and hasattr(model, "q_net_target"):
        return model.q_net, model.q_net_target, model.policy.optimizer
    raise ValueError(
        f"reset_critic: {type(model).__name__} has no critic (critic/critic_target or "
        "q_net/q_net_target); pass reset_critic=False"
    )


def reset_critic(model: BaseAlgorithm, updates: int) -> None:
    """Fresh critic weights, its target a copy, its optimiser's moments cleared (seqrank's
    `SAC.reset_critic`); then `updates` agent updates on the relabelled buffer."""
    critic, target, optimizer = critic_parts(model)
    for module in critic.modules():
        reset = getattr(module, "reset_parameters", None)
        if module is not critic and callable(reset):
            reset()
    target.load_state_dict(critic.state_dict())
    optimizer.state.clear()
    if updates and isinstance(model, OffPolicyAlgorithm):
        model.train(gradient_steps=updates, batch_size=model.batch_size)


class EntropyBatches:
    """While installed, each batch an off-policy agent samples carries the state-entropy
    reward (k-NN distance of its observations to every stored one, over its running
    standard deviation: `reward.entropy`). Installed on the buffer object itself, and taken
    off before the buffer is saved."""

    def __init__(self, knn_k: int, stats: RunningMeanStd):
        self.knn_k, self.stats = knn_k, stats
        self._installed: ReplayTable | None = None

    def install(self, table: ReplayTable) -> None:
        self.remove()
        original: Callable[..., Any] = table.buffer.sample

        def sample(batch_size: int, env: Any = None) -> Any:
            batch = original(batch_size, env)
            stored = table.stored_observations().to(batch.observations.device)
            queries = batch.observations.reshape(len(batch.observations), -1).float()
            reward = intrinsic_reward(queries, stored, self.knn_k, self.stats)
            return batch._replace(rewards=reward.to(batch.rewards.dtype))

        table.buffer.sample = sample  # type: ignore[method-assign]
        self._installed = table

    def remove(self) -> None:
        if self._installed is not None:
            del self._installed.buffer.sample  # the class's own method again
            self._installed = None
