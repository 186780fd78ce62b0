"""Replay buffer (a ring on the training device) and the store of recent episodes.

The replay buffer keeps the true reward beside the learned one, so the learned reward can
be recomputed for every stored transition after each reward update, also after the ring
has wrapped (the reference code only relabels up to the write index).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

RewardFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


@dataclass(frozen=True)
class Batch:
    obs: torch.Tensor
    action: torch.Tensor
    reward: torch.Tensor  # learned reward, shape (B, 1)
    next_obs: torch.Tensor
    not_done: torch.Tensor  # 0 only at true terminals; time limits are not terminal


class ReplayBuffer:
    def __init__(self, capacity: int, obs_dim: int, act_dim: int, device: torch.device):
        self.capacity, self.device = capacity, device

        def zeros(*shape: int) -> torch.Tensor:
            return torch.zeros((capacity, *shape), dtype=torch.float32, device=device)

        self.obs, self.next_obs = zeros(obs_dim), zeros(obs_dim)
        self.action = zeros(act_dim)
        self.true_reward, self.reward, self.not_done = zeros(1), zeros(1), zeros(1)
        self.index, self.size = 0, 0

    def __len__(self) -> int:
        return self.size

    def add(
        self,
        obs: np.ndarray,
        action: np.ndarray,
        true_reward: float,
        learned_reward: float,
        next_obs: np.ndarray,
        terminated: bool,
    ) -> None:
        i = self.index
        self.obs[i] = torch.as_tensor(obs, device=self.device)
        self.action[i] = torch.as_tensor(action, device=self.device)
        self.next_obs[i] = torch.as_tensor(next_obs, device=self.device)
        self.true_reward[i, 0] = float(true_reward)
        self.reward[i, 0] = float(learned_reward)
        self.not_done[i, 0] = 0.0 if terminated else 1.0
        self.index = (i + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, batch_size: int, generator: torch.Generator) -> Batch:
        idx = torch.randint(0, self.size, (batch_size,), generator=generator).to(self.device)
        return Batch(
            self.obs[idx],
            self.action[idx],
            self.reward[idx],
            self.next_obs[idx],
            self.not_done[idx],
        )

    def relabel(self, reward_fn: RewardFn, chunk: int = 8192) -> None:
        """Recompute the learned reward of every stored transition (the whole ring)."""
        with torch.no_grad():
            for start in range(0, self.size, chunk):
                stop = min(start + chunk, self.size)
                self.reward[start:stop] = reward_fn(self.obs[start:stop], self.action[start:stop])

    def state_dict(self) -> dict[str, Any]:
        n = self.size
        return {
            "index": self.index,
            "size": n,
            "obs": self.obs[:n].cpu(),
            "next_obs": self.next_obs[:n].cpu(),
            "action": self.action[:n].cpu(),
            "true_reward": self.true_reward[:n].cpu(),
            "reward": self.reward[:n].cpu(),
            "not_done": self.not_done[:n].cpu(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        n = state["size"]
        for name in ("obs", "next_obs", "action", "true_reward", "reward", "not_done"):
            getattr(self, name)[:n] = state[name].to(self.device)
        self.index, self.size = state["index"], n


@dataclass
class Episode:
    obs: np.ndarray  # (T, obs_dim) observation before each action
    action: np.ndarray  # (T, act_dim)
    reward: np.ndarray  # (T,) true reward
    context: int | None = None  # Meta-World task index, to re-render
    states: np.ndarray | None = None  # (T, state_dim) physics states, when recorded


@dataclass(frozen=True)
class Segments:
    """Segments cut from episodes: what the reward model sees, the truth, and provenance."""

    features: np.ndarray  # (N, H, obs + act)
    rewards: np.ndarray  # (N, H) true per-step rewards
    states: list[np.ndarray | None]  # (H, state_dim) physics states when recorded
    contexts: list[int | None]  # Meta-World task index, to re-render


class EpisodeStore:
    """The last `keep` complete episodes; feedback segments are cut from them."""

    def __init__(self, keep: int):
        self.episodes: deque[Episode] = deque(maxlen=keep)

    def __len__(self) -> int:
        return len(self.episodes)

    def add(self, episode: Episode) -> None:
        self.episodes.append(episode)

    def recent_returns(self, count: int) -> np.ndarray:
        return np.array([e.reward.sum() for e in list(self.episodes)[-count:]])

    def sample_segments(self, count: int, length: int, rng: np.random.Generator) -> Segments:
        """`count` segments cut at a uniform episode and a uniform start."""
        episodes = list(self.episodes)
        which = rng.integers(len(episodes), size=count)
        features, rewards, states, contexts = [], [], [], []
        for e in which:
            episode = episodes[e]
            start = int(rng.integers(len(episode.reward) - length + 1))
            stop = start + length
            features.append(
                np.concatenate([episode.obs[start:stop], episode.action[start:stop]], 1)
            )
            rewards.append(episode.reward[start:stop])
            states.append(None if episode.states is None else episode.states[start:stop])
            contexts.append(episode.context)
        return Segments(np.stack(features).astype(np.float32), np.stack(rewards), states, contexts)

    def state_dict(self) -> dict[str, Any]:
        return {"keep": self.episodes.maxlen, "episodes": list(self.episodes)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.episodes = deque(state["episodes"], maxlen=state["keep"])
