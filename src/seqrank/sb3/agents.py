"""What the feedback does to an SB3 agent: PEBBLE's critic reset after the first session,
and, before it, the state-entropy reward of unsupervised pre-training in the batches an
off-policy agent samples (PEBBLE computes it per batch, against every stored state); and
whether the agent acts on the feedback's environment at all."""

from __future__ import annotations

from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv
from torch import nn

from seqrank.reward.entropy import RunningMeanStd, intrinsic_reward
from seqrank.sb3.tables import ReplayTable


def is_off_policy(model: BaseAlgorithm) -> bool:
    return isinstance(model, OffPolicyAlgorithm)


def acts_on(model: BaseAlgorithm, env: VecEnv) -> bool:
    """Whether `model` steps `env`, directly or through wrappers of it (VecNormalize, ...)."""
    venv: Any = model.get_env()
    while venv is not None:
        if venv is env:
            return True
        venv = getattr(venv, "venv", None)
    return False


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


class EntropySample:
    """The replay buffer's `sample` while pre-training: SB3's own batch, its rewards the
    state-entropy reward (k-NN distance of each observation to every stored one, over the
    running standard deviation: `reward.entropy`).

    A module-level object, not a closure, so the buffer pickles at any step (SB3's
    `save_replay_buffer`, `CheckpointCallback(save_replay_buffer=True)`); it pickles as the
    buffer's own `sample` method, so a buffer saved during pre-training loads as SB3 made
    it, with no seqrank state inside."""

    def __init__(self, table: ReplayTable, knn_k: int, stats: RunningMeanStd, original: Any):
        self.table, self.knn_k, self.stats, self.original = table, knn_k, stats, original

    def __call__(self, batch_size: int, env: Any = None) -> Any:
        batch = self.original(batch_size, env)
        stored = self.table.stored_observations().to(batch.observations.device)
        queries = batch.observations.reshape(len(batch.observations), -1).float()
        reward = intrinsic_reward(queries, stored, self.knn_k, self.stats)
        return batch._replace(rewards=reward.to(batch.rewards.dtype))

    def __reduce__(self) -> tuple[Any, ...]:
        # unpickled while the buffer's own attributes are not yet restored: the class's method
        return (getattr, (self.table.buffer, "sample"))


class EntropyBatches:
    """While installed, each batch an off-policy agent samples carries the state-entropy
    reward (`EntropySample`, set as the buffer's `sample`); removed at the first session
    and when training ends, which puts back the buffer's own `sample`."""

    def __init__(self, knn_k: int, stats: RunningMeanStd):
        self.knn_k, self.stats = knn_k, stats
        self._installed: ReplayTable | None = None
        self._own: Any = None  # a `sample` the buffer object had of its own, put back

    def install(self, table: ReplayTable) -> None:
        self.remove()
        buffer = table.buffer
        self._own = vars(buffer).get("sample")
        buffer.sample = EntropySample(  # type: ignore[method-assign]
            table, self.knn_k, self.stats, buffer.sample
        )
        self._installed = table

    def remove(self) -> None:
        if self._installed is None:
            return
        buffer = self._installed.buffer
        if self._own is None:
            del buffer.sample  # the class's own method again
        else:
            buffer.sample = self._own  # type: ignore[method-assign]
        self._installed = self._own = None
