"""A seqrank task behind the plain Gymnasium interface, as `gymnasium.make("seqrank/...")`
builds it (`seqrank.registration`): `render()` gives RGB frames with
`render_mode="rgb_array"`, everything else is the task's own `SimEnv`."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import EnvSpec

from seqrank.envs.suites import make_env

RENDER_MODES = ("rgb_array",)
FRAME_SIZE = 256  # pixels a side of a rendered frame, unless width and height are given


class TaskEnv(gym.Env[np.ndarray, np.ndarray]):
    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 30}  # noqa: RUF012

    def __init__(
        self,
        task: str,
        render_mode: str | None = None,
        width: int = FRAME_SIZE,
        height: int = FRAME_SIZE,
    ):
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode {render_mode!r}; accepted: rgb_array or None")
        self.task = make_env(task)
        self.render_mode, self.width, self.height = render_mode, width, height
        self.observation_space = self.task.observation_space
        self.action_space = self.task.action_space
        # the task ends its episodes itself (truncated at this step): what a TimeLimit says
        self.max_episode_steps = self.task.episode_length
        self._spec: EnvSpec | None = None

    @property
    def spec(self) -> EnvSpec | None:
        """The registered spec with the task's episode length (what `TimeLimit` users read,
        SB3 and `gymnasium.make(spec)` among them); the task truncates there itself."""
        return self._spec

    @spec.setter
    def spec(self, spec: EnvSpec | None) -> None:  # gymnasium.make sets it after __init__
        self._spec = (
            None if spec is None else replace(spec, max_episode_steps=self.max_episode_steps)
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        return self.task.reset(seed=seed, options=options)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.task.step(action)
        return obs, float(reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            return None
        return self.task.render_frame(self.width, self.height)

    def close(self) -> None:
        self.task.close()


def make_task(task: str, **options: Any) -> TaskEnv:
    """Gymnasium's entry point for the `seqrank/...` ids."""
    return TaskEnv(task, **options)
