"""IQL's hyperparameters, without torch: `seqrank.offline.settings` takes its defaults
from here (`seqrank --help` imports no torch)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class IQLSettings:
    """The published MuJoCo hyperparameters by default (`configs/mujoco_config.py`)."""

    hidden: int = 256
    layers: int = 2
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    value_lr: float = 3e-4
    discount: float = 0.99
    expectile: float = 0.7  # tau: V tracks this expectile of Q over the dataset's actions
    temperature: float = 3.0  # beta: 0 is behaviour cloning, larger trusts Q more
    target_rate: float = 0.005  # the target critic's soft update
    max_weight: float = 100.0  # the advantage weight's clip
    decay_steps: int = 1_000_000  # the actor's cosine schedule reaches 0 here; 0: constant
