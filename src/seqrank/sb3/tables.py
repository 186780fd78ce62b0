"""Where an SB3 agent's learned rewards live, as reward learning's `RewardTable`: an
off-policy agent's replay buffer (relabelled in place after every session), or, for an
on-policy agent (rewards given at rollout time, nothing stored to relabel), the episode
store."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from stable_baselines3.common.buffers import ReplayBuffer

from seqrank.buffer import RewardFn
from seqrank.episodes import EpisodeStore
from seqrank.sb3.envs import canonical_actions


class ReplayTable:
    """An SB3 `ReplayBuffer`, with the true reward of each stored transition kept beside it
    (`true`, same layout as `buffer.rewards`, written as each transition is stored)."""

    def __init__(self, buffer: ReplayBuffer, device: torch.device, true: np.ndarray | None = None):
        self.buffer, self.device = buffer, device
        self.true = np.zeros_like(buffer.rewards) if true is None else true

    @property
    def size(self) -> int:
        return self.buffer.buffer_size if self.buffer.full else self.buffer.pos

    def features(self, stop: int, start: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Observations and canonical actions of rows `start:stop`, one transition a row."""
        obs = self.buffer.observations[start:stop]
        actions = self.buffer.actions[start:stop]
        rows = obs.shape[0] * obs.shape[1]
        flat_actions = actions.reshape(rows, -1)
        space = self.buffer.action_space
        if not hasattr(space, "n"):  # a Box: stored scaled to [-1, 1] already
            return obs.reshape(rows, -1).astype(np.float32), flat_actions.astype(np.float32)
        return obs.reshape(rows, -1).astype(np.float32), canonical_actions(space, flat_actions)

    def store_true(self, rewards: np.ndarray) -> None:
        """The true rewards of the transitions about to be stored (at `buffer.pos`)."""
        self.true[self.buffer.pos] = rewards

    def relabel(self, reward_fn: RewardFn, chunk: int = 8192) -> None:
        n_envs = self.buffer.n_envs
        step = max(chunk // n_envs, 1)
        with torch.no_grad():
            for start in range(0, self.size, step):
                stop = min(start + step, self.size)
                obs, actions = self.features(stop, start)
                obs_t, actions_t = torch.from_numpy(obs), torch.from_numpy(actions)
                learned = reward_fn(obs_t.to(self.device), actions_t.to(self.device))
                self.buffer.rewards[start:stop] = learned.cpu().numpy().reshape(-1, n_envs)

    def reward_sample(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        rows = self.size * self.buffer.n_envs
        idx = rng.choice(rows, size=min(rows, count), replace=False)
        learned = self.buffer.rewards[: self.size].reshape(-1)[idx]
        return learned.astype(np.float32), self.true[: self.size].reshape(-1)[idx]

    def state_dict(self) -> dict[str, Any]:
        return {"true": self.true.copy()}


class EpisodeTable:
    """The kept episodes: an on-policy agent's rewards need no relabelling; the reward's
    correlation with the truth is measured over these steps."""

    def __init__(self, episodes: EpisodeStore, reward_fn: RewardFn, device: torch.device):
        self.episodes, self.reward_fn, self.device = episodes, reward_fn, device

    def relabel(self, reward_fn: RewardFn, chunk: int = 8192) -> None:
        pass

    def reward_sample(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        episodes = list(self.episodes.episodes)
        if not episodes:
            return np.zeros(0, np.float32), np.zeros(0)
        obs = np.concatenate([e.obs for e in episodes])
        actions = np.concatenate([e.action for e in episodes])
        true = np.concatenate([e.reward for e in episodes])
        idx = rng.choice(len(true), size=min(len(true), count), replace=False)
        with torch.no_grad():
            obs_t, actions_t = torch.from_numpy(obs[idx]), torch.from_numpy(actions[idx])
            learned = self.reward_fn(obs_t.to(self.device), actions_t.to(self.device))
        return learned.reshape(-1).cpu().numpy(), true[idx]
