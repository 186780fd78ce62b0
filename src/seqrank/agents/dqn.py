"""DQN for the discrete block-placing task (supplementary D.1), trained on the learned reward.

Double DQN with a Huber loss and a soft-updated target network. Actions are one-hot
vectors (what the replay buffer and the reward model see). Exploration follows D.1:
epsilon 1.0 for the first `seed_steps` steps (the trainer acts at random then), afterwards
0.5, multiplied by 0.98 every 100 steps, never below 0.1.

It satisfies the `Agent` protocol, so PEBBLE's loop runs it unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from seqrank.agents.networks import mlp
from seqrank.agents.update_steps import descend, soft_update
from seqrank.buffer import Batch, BatchSource


@dataclass(frozen=True)
class EpsilonSchedule:
    random_steps: int = 1_000
    start: float = 0.5
    decay: float = 0.98
    every: int = 100
    floor: float = 0.1

    def at(self, step: int) -> float:
        if step < self.random_steps:
            return 1.0
        decays = (step - self.random_steps) // self.every
        return max(self.floor, self.start * self.decay**decays)


@dataclass(frozen=True, kw_only=True)
class DQNSettings:
    """DQN's sizes and constants (keywords only: seven numbers in a row are easy to swap)."""

    hidden: int
    layers: int
    lr: float
    discount: float
    tau: float
    target_update_every: int
    epsilon: EpsilonSchedule


class DQN:
    def __init__(self, obs_dim: int, actions: int, settings: DQNSettings, device: torch.device):
        self.obs_dim, self.actions, self.settings, self.device = obs_dim, actions, settings, device
        self.acted = 0  # exploratory actions taken, after the random steps
        self.updates = 0
        self.last_metrics: dict[str, float] = {}
        self.reset_critic()

    def reset_critic(self) -> None:
        """A fresh Q network, target and optimiser."""
        s = self.settings
        self.q = mlp(self.obs_dim, s.hidden, s.layers, self.actions).to(self.device)
        self.q_target = mlp(self.obs_dim, s.hidden, s.layers, self.actions).to(self.device)
        self.q_target.load_state_dict(self.q.state_dict())
        self.optimizer = torch.optim.Adam(self.q.parameters(), lr=s.lr)

    @property
    def epsilon(self) -> float:
        return self.settings.epsilon.at(self.settings.epsilon.random_steps + self.acted)

    @torch.no_grad()
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> np.ndarray:
        """One-hot action: greedy, or epsilon-greedy while training."""
        if not deterministic:
            epsilon = self.epsilon
            self.acted += 1
            if float(torch.rand(1, generator=generator)) < epsilon:
                return _one_hot(
                    int(torch.randint(self.actions, (1,), generator=generator)), self.actions
                )
        obs_t = torch.as_tensor(obs, dtype=torch.float32, device=self.device).unsqueeze(0)
        return _one_hot(int(self.q(obs_t).argmax(dim=-1)), self.actions)

    def update_from(self, replay: BatchSource, batch_size: int, generator: torch.Generator) -> None:
        self.update(replay.sample(batch_size, generator), generator)

    def update(self, batch: Batch, generator: torch.Generator) -> None:
        action = batch.action.argmax(dim=-1, keepdim=True)
        q = self.q(batch.obs).gather(1, action)
        with torch.no_grad():  # double DQN: the online net picks, the target net values
            best = self.q(batch.next_obs).argmax(dim=-1, keepdim=True)
            next_value = self.q_target(batch.next_obs).gather(1, best)
            target = batch.reward + self.settings.discount * batch.not_done * next_value
        loss = F.smooth_l1_loss(q, target)
        descend(self.optimizer, loss)
        self.updates += 1
        if self.updates % self.settings.target_update_every == 0:
            soft_update(self.q_target.parameters(), self.q.parameters(), self.settings.tau)
        self.last_metrics = {
            "q_loss": float(loss.detach()),
            "q_mean": float(q.detach().mean()),
            "epsilon": self.epsilon,
        }

    def eval_metrics(self) -> dict[str, float]:
        return {"epsilon": self.epsilon}

    def state_dict(self) -> dict[str, Any]:
        return {
            "q": self.q.state_dict(),
            "q_target": self.q_target.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "acted": self.acted,
            "updates": self.updates,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.q.load_state_dict(state["q"])
        self.q_target.load_state_dict(state["q_target"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.acted, self.updates = state["acted"], state["updates"]


def _one_hot(index: int, size: int) -> np.ndarray:
    vector = np.zeros(size, np.float32)
    vector[index] = 1.0
    return vector
