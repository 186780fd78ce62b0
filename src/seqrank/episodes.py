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
    """The last `keep` complete episodes; feedback segments are cut from them. `added`
    counts every episode ever added, so the stored ones are numbers `added - len` to
    `added - 1`."""

    def __init__(self, keep: int):
        self.episodes: deque[Episode] = deque(maxlen=keep)
        self.added = 0

    def __len__(self) -> int:
        return len(self.episodes)

    def add(self, episode: Episode) -> None:
        self.episodes.append(episode)
        self.added += 1

    def window(self, last: int = 0) -> tuple[int, int]:
        """The numbers of the first and last episode that `sample_segments(..., last)`
        cuts from: the last `last` stored (all of them for 0)."""
        held = len(self.episodes) if last == 0 else min(last, len(self.episodes))
        return self.added - held, self.added - 1

    def recent_returns(self, count: int) -> np.ndarray:
        return np.array([e.reward.sum() for e in list(self.episodes)[-count:]])

    def sample_segments(
        self,
        count: int,
        length: int,
        rng: np.random.Generator,
        last: int = 0,
        in_order: bool = False,
    ) -> Segments:
        """`count` segments cut at a uniform episode and a uniform start; with `last`, a
        uniform episode of the last `last` stored (QPA's policy-aligned queries); with
        `in_order`, the same segments (the same draws) in the order they were collected:
        by `collected` (the episode), then by start.

        An episode shorter than `length` (a Gymnasium task that ended in a terminal state)
        gives its whole self, padded with its last step repeated at zero true reward: what
        an absorbing terminal state would show.
        """
        episodes = list(self.episodes)[-last:] if last else list(self.episodes)
        which = rng.integers(len(episodes), size=count)
        starts = [int(rng.integers(max(len(episodes[e].reward) - length, 0) + 1)) for e in which]
        order = range(count)
        if in_order:
            keys = (np.array(starts), which, self.collected(which, last))
            order = np.lexsort(keys).tolist()
        features, rewards, states, contexts = [], [], [], []
        for k in order:
            episode, start = episodes[which[k]], starts[k]
            stop = start + length
            obs, action = (
                _pad(episode.obs[start:stop], length),
                _pad(episode.action[start:stop], length),
            )
            features.append(np.concatenate([obs, action], 1))
            reward = episode.reward[start:stop]
            rewards.append(np.concatenate([reward, np.zeros(length - len(reward))]))
            states.append(
                None if episode.states is None else _pad(episode.states[start:stop], length)
            )
            contexts.append(episode.context)
        return Segments(np.stack(features).astype(np.float32), np.stack(rewards), states, contexts)

    def collected(self, which: np.ndarray, last: int = 0) -> np.ndarray:
        """When the episodes `which` (positions among those `sample_segments` cuts from)
        were collected, as a sort key: their positions, stored in the order added."""
        return which

    def state_dict(self) -> dict[str, Any]:
        return {"keep": self.episodes.maxlen, "episodes": list(self.episodes), "added": self.added}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.episodes = deque(state["episodes"], maxlen=state["keep"])
        self.added = state.get("added", len(self.episodes))  # (older checkpoints: unknown)


def _pad(rows: np.ndarray, length: int) -> np.ndarray:
    """`rows` with its last row repeated up to `length` rows."""
    missing = length - len(rows)
    return rows if missing <= 0 else np.concatenate([rows, np.repeat(rows[-1:], missing, 0)])
