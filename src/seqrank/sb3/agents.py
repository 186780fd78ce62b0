"""What the feedback does to an SB3 agent: PEBBLE's critic reset after the first session
(the state-entropy reward before it is the replay buffer's, `replay.py`); and whether the
agent acts on the feedback's environment at all."""

from __future__ import annotations

from typing import Any

import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv
from torch import nn


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
