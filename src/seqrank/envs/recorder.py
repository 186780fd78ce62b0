"""Recording an episode as it is played: observations, actions, true rewards and, when
asked for, the physics state before each step (to re-render a segment as a clip later).
Training and the offline labelling rollout share it."""

from __future__ import annotations

from typing import Any

import numpy as np

from seqrank.envs.base import SimEnv
from seqrank.episodes import Episode


class EpisodeRecorder:
    def __init__(self, record_states: bool):
        self.record_states = record_states
        self._columns: dict[str, list[Any]] = _empty()

    def before_step(self, env: SimEnv) -> None:
        """Call before `env.step`: keeps the state the step starts from."""
        if self.record_states:
            self._columns["states"].append(env.get_state())

    def add(self, obs: np.ndarray, action: np.ndarray, reward: float) -> None:
        for key, value in (("obs", obs), ("action", action), ("reward", reward)):
            self._columns[key].append(value)

    def finish(self, context: int | None) -> Episode:
        """The episode recorded since the last `finish`; `context` is Meta-World's task."""
        columns, self._columns = self._columns, _empty()
        return Episode(
            np.asarray(columns["obs"], np.float32),
            np.asarray(columns["action"], np.float32),
            np.asarray(columns["reward"], np.float64),
            context,
            np.asarray(columns["states"]) if columns["states"] else None,
        )


def _empty() -> dict[str, list[Any]]:
    return {"obs": [], "action": [], "reward": [], "states": []}
