"""Tiny Gymnasium tasks for the SB3 tests: cheap to step, quick to learn."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

EPISODE = 50  # steps, no terminal states: every episode ends by its time limit
SENTINEL = 1e9  # the true reward of `make_sentinel`: never seen by an agent


class Line(gym.Env[np.ndarray, np.ndarray]):
    """A point on a line that should stay at a target: observation (x, target), action a
    step of at most 0.2 (the first of `act_dim` numbers); reward minus the distance."""

    def __init__(self, sentinel: bool = False, act_dim: int = 1):
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (act_dim,), np.float32)
        self.sentinel = sentinel
        self._x = self._target = 0.0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._x, self._target = (float(v) for v in self.np_random.uniform(-0.9, 0.9, 2))
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self._x = float(np.clip(self._x + 0.2 * float(np.asarray(action).reshape(-1)[0]), -1, 1))
        reward = SENTINEL if self.sentinel else -abs(self._x - self._target)
        return self._obs(), reward, False, False, {}

    def _obs(self) -> np.ndarray:
        return np.array([self._x, self._target], np.float32)


def make_line() -> gym.Env[np.ndarray, np.ndarray]:
    return gym.wrappers.TimeLimit(Line(), max_episode_steps=EPISODE)


def make_sentinel() -> gym.Env[np.ndarray, np.ndarray]:
    """The line whose true reward is a huge constant: an agent that saw it would store it."""
    return gym.wrappers.TimeLimit(Line(sentinel=True), max_episode_steps=EPISODE)


def make_wide_line() -> gym.Env[np.ndarray, np.ndarray]:
    """The line with a 3-number action (only the first moves the point)."""
    return gym.wrappers.TimeLimit(Line(act_dim=3), max_episode_steps=EPISODE)
