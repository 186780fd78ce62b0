"""Recorded episodes and the segments cut from them for feedback."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np


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
