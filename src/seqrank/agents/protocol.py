"""The agent contract: everything the training loop asks of an agent.

SAC and DQN satisfy it; MRN wraps another agent's update (`mrn.MetaRewardUpdate`). A new
agent is added by satisfying this protocol and building it in `training/agent_factory.py`.
"""

from __future__ import annotations

from typing import Any, Protocol

import torch

from seqrank.buffer import Batch, BatchSource


class Policy(Protocol):
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> Any:
        """An action for one observation; `deterministic` for evaluation."""
        ...


class Agent(Policy, Protocol):
    @property
    def last_metrics(self) -> dict[str, float]:
        """The last update's losses by name (logged as `train` rows)."""
        ...

    def eval_metrics(self) -> dict[str, float]:
        """Values logged beside each evaluation (SAC's temperature, DQN's epsilon)."""
        ...

    def update(self, batch: Batch, generator: torch.Generator) -> None:
        """One learning step on a given batch (pre-training, MRN, after a critic reset)."""
        ...

    def update_from(self, replay: BatchSource, batch_size: int, generator: torch.Generator) -> None:
        """One learning step on a batch the agent samples from `replay` (the hot loop)."""
        ...

    def reset_critic(self) -> None:
        """Forget the value function (PEBBLE, after the first reward model); keep the policy."""
        ...

    def state_dict(self) -> dict[str, Any]: ...

    def load_state_dict(self, state: dict[str, Any]) -> None: ...
