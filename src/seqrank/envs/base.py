"""What every simulated task offers: gymnasium spaces, rendering and physics state."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # headless; must be set before MuJoCo loads GL

from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

FULL_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


class SimEnv(gym.Env[np.ndarray, np.ndarray]):
    """What the two suites share: spaces, rendering, physics state."""

    name: str
    episode_length: int
    discrete = False  # True: actions are one-hot choices (block:place, learned with DQN)
    # "state": clips are re-rendered from saved physics states; "frames": get_state() is
    # the frame itself, recorded while playing (a Gymnasium task without MuJoCo state)
    clip_source = "state"
    has_terminals = False  # True: episodes may end before `episode_length` (Gymnasium tasks)
    _model: Any
    _data: Any

    def canonical_action(self, action: np.ndarray) -> np.ndarray:
        """The action as stored for learning (block:place turns scores into a one-hot)."""
        return action

    def _set_spaces(self, obs_dim: int, act_dim: int) -> None:
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (act_dim,), np.float32)
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}

    @property
    def obs_dim(self) -> int:
        return int(self.observation_space.shape[0])  # type: ignore[index]

    @property
    def act_dim(self) -> int:
        return int(self.action_space.shape[0])  # type: ignore[index]

    def get_state(self) -> np.ndarray:
        """The full physics state of the current step (float64 vector)."""
        state = np.empty(mujoco.mj_stateSize(self._model, FULL_STATE), dtype=np.float64)
        mujoco.mj_getState(self._model, self._data, state, FULL_STATE)
        return state

    def set_state(self, state: np.ndarray) -> None:
        mujoco.mj_setState(self._model, self._data, np.asarray(state, np.float64), FULL_STATE)
        mujoco.mj_forward(self._model, self._data)

    def render_frame(self, width: int = 128, height: int = 128) -> np.ndarray:
        """An RGB uint8 frame (height, width, 3) of the current state."""
        renderer = self._renderers.get((width, height))
        if renderer is None:
            renderer = mujoco.Renderer(self._model, height, width)
            self._renderers[(width, height)] = renderer
        renderer.update_scene(self._data, camera=self._camera)
        if self._fast_rendering:
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        frame = renderer.render()
        return frame[::-1].copy() if self._flip else frame

    def render_states(
        self, states: np.ndarray, context: int | None = None, width: int = 128, height: int = 128
    ) -> np.ndarray:
        """Frames (T, height, width, 3) of saved states; `context` is the episode's task."""
        self.restore_context(context)
        frames = []
        for state in states:
            self.set_state(state)
            frames.append(self.render_frame(width, height))
        return np.stack(frames)

    def restore_context(self, context: int | None) -> None:
        """Make the episode-level setting (Meta-World's task) current again."""

    _camera: int | str | mujoco.MjvCamera = 0
    _flip = False
    _fast_rendering = False

    def check_clips(self) -> None:
        """Raise SettingError when the labelling page could not show this task's clips
        (a MuJoCo task always can: its states are re-rendered)."""

    def use_fast_rendering(self) -> None:
        """No shadows, reflections or anti-aliasing: about 8x faster (labelling clips)."""
        self._fast_rendering = True
        self._model.vis.quality.offsamples = 0
        self.close()  # renderers made from now on use the model's new settings

    def close(self) -> None:
        for renderer in self._renderers.values():
            renderer.close()
        self._renderers.clear()
