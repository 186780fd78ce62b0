"""A fixed dataset of episodes in memory: what the labelling, the reward model and the
offline learner read. Reading and writing Minari datasets lives in its own module; this
one holds the arrays and the views of them each consumer needs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from seqrank.episodes import Episode, EpisodeStore


@dataclass(frozen=True)
class OfflineDataset:
    """Episodes back to back: row i is one transition; `starts[e]` is episode e's first
    row and `starts[e + 1]` (or the row count) one past its last."""

    task: str  # seqrank's canonical task name (`envs.canonical_task`)
    observations: np.ndarray  # (N, obs_dim) float32, before each action
    actions: np.ndarray  # (N, act_dim) float32
    rewards: np.ndarray  # (N,) float32, the environment's true reward
    next_observations: np.ndarray  # (N, obs_dim) float32
    terminations: np.ndarray  # (N,) bool: a terminal state (no bootstrap)
    truncations: np.ndarray  # (N,) bool: the episode was cut (time limit)
    starts: np.ndarray  # (E,) int64, ascending, starts[0] == 0
    meta: dict[str, Any] = field(default_factory=dict)  # provenance: source, seeds, sizes

    def __post_init__(self) -> None:
        rows = len(self.observations)
        columns = (self.actions, self.rewards, self.next_observations, self.terminations,
                   self.truncations)  # fmt: skip
        if any(len(column) != rows for column in columns):
            raise ValueError("every column of a dataset must have one row per transition")
        if not len(self.starts) or self.starts[0] != 0 or np.any(np.diff(self.starts) <= 0):
            raise ValueError("episode starts must begin at 0 and rise strictly")
        if self.starts[-1] >= rows:
            raise ValueError("the last episode start is past the last transition")

    def __len__(self) -> int:
        return len(self.observations)

    @property
    def episode_count(self) -> int:
        return len(self.starts)

    @property
    def obs_dim(self) -> int:
        return int(self.observations.shape[1])

    @property
    def act_dim(self) -> int:
        return int(self.actions.shape[1])

    def bounds(self, episode: int) -> tuple[int, int]:
        """The rows [first, stop) of one episode."""
        stop = self.starts[episode + 1] if episode + 1 < len(self.starts) else len(self)
        return int(self.starts[episode]), int(stop)

    def episodes(self) -> list[Episode]:
        """The episodes as the feedback code cuts segments from them."""
        out = []
        for e in range(self.episode_count):
            first, stop = self.bounds(e)
            rewards = self.rewards[first:stop].astype(np.float64)
            out.append(Episode(self.observations[first:stop], self.actions[first:stop], rewards))
        return out

    def episode_store(self) -> EpisodeStore:
        store = EpisodeStore(max(self.episode_count, 1))
        for episode in self.episodes():
            store.add(episode)
        return store

    def episode_returns(self) -> np.ndarray:
        return np.add.reduceat(self.rewards.astype(np.float64), self.starts)
