"""Your own environment as a seqrank task: a point that must reach a goal on a plane.

From the repository root:

    seqrank train --task examples.point_reach:make_env --steps 20000 --feedback-frequency 3000
    seqrank label offline --task examples.point_reach:make_env --questions 10 --out labels

`module.path:factory` names a function that returns a `gymnasium.Env` with Box observation
and action spaces and a time limit. This one has no MuJoCo state, so it is made with
`render_mode="rgb_array"`: the labelling page's clips are the frames recorded while the
episode was played. Reaching the goal is a terminal state (no bootstrapping past it).
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

SIDE = 96  # pixels of a rendered frame


class PointReach(gym.Env[np.ndarray, np.ndarray]):
    """Observation (x, y, goal x, goal y); action a velocity; reward minus the distance."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, render_mode: str | None = None):
        self.render_mode = render_mode
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
        self.action_space = gym.spaces.Box(-0.1, 0.1, (2,), np.float32)  # rescaled by seqrank
        self._point = np.zeros(2)
        self._goal = np.zeros(2)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._point = self.np_random.uniform(-0.9, 0.9, 2)
        self._goal = self.np_random.uniform(-0.9, 0.9, 2)
        return self._obs(), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self._point = np.clip(self._point + np.asarray(action, np.float64), -1.0, 1.0)
        distance = float(np.linalg.norm(self._point - self._goal))
        reached = distance < 0.05
        return self._obs(), -distance, reached, False, {"success": reached}

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        if self.render_mode != "rgb_array":
            return None
        frame = np.full((SIDE, SIDE, 3), 235, np.uint8)
        for position, colour in ((self._goal, (40, 160, 60)), (self._point, (200, 40, 40))):
            col, row = ((position + 1.0) / 2.0 * (SIDE - 1)).astype(int)
            frame[max(row - 3, 0) : row + 4, max(col - 3, 0) : col + 4] = colour
        return frame

    def _obs(self) -> np.ndarray:
        return np.concatenate([self._point, self._goal]).astype(np.float32)


def make_env() -> gym.Env[np.ndarray, np.ndarray]:
    """The factory `--task examples.point_reach:make_env` calls."""
    return gym.wrappers.TimeLimit(PointReach(render_mode="rgb_array"), max_episode_steps=100)
