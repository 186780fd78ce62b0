"""Any Gymnasium environment with Box spaces behind the `SimEnv` interface.

`--task gym:Hopper-v5` makes a registered environment; `--task my_pkg.envs:make` calls a
user's factory (no arguments) that returns a `gymnasium.Env`. Unlike the paper's suites,
these tasks have terminal states: `terminated` ends an episode and stops bootstrapping,
the time limit (`truncated`) does not.

Clips for the labelling page come from one of two places, `clip_source` says which:
- "state": the environment is MuJoCo (it exposes `model` and `data`), so a segment's
  physics states are saved and re-rendered later, as for DMControl;
- "frames": anything else; `env.render()` frames (the factory must make the environment
  with `render_mode="rgb_array"`) are recorded during the rollout when clips are needed,
  at most `FRAME_SIDE` pixels a side.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from seqrank.envs.base import SimEnv
from seqrank.errors import SettingError, setting

FRAME_SIDE = 128  # recorded frames are downscaled to at most this many pixels a side


def check_gym_id(env_id: str) -> None:
    """Raise ValueError unless `env_id` is a registered Gymnasium environment."""
    if env_id not in gym.registry:
        known = sorted(i for i in gym.registry if i.endswith("-v5") and "Pusher" not in i)
        raise ValueError(
            f"unknown Gymnasium environment {env_id!r}; accepted: any registered id, "
            f"e.g. {', '.join(known[:6])}"
        )


def load_factory(spec: str) -> Callable[[], gym.Env[Any, Any]]:
    """The callable named by 'module.path:factory' (ValueError naming what is missing)."""
    module_name, _, attribute = spec.partition(":")
    if "" not in sys.path and os.getcwd() not in sys.path:
        sys.path.append(os.getcwd())  # as `python -m` does: a module beside you is found
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise SettingError(
            f"{setting('task')} {spec!r}: cannot import module {module_name!r} ({error}); a custom "
            "task is 'module.path:factory' with the module importable (on PYTHONPATH or in the "
            "current directory)"
        ) from None
    factory = getattr(module, attribute, None)
    if not callable(factory):
        raise SettingError(
            f"{setting('task')} {spec!r}: module {module_name!r} has no callable {attribute!r}; a "
            "custom task is 'module.path:factory', a function that returns a gymnasium.Env"
        )
    return factory


class GymEnv(SimEnv):
    """A Gymnasium environment with flat float32 observations and actions in [-1, 1]."""

    clip_source = "frames"  # until the environment shows MuJoCo model and data
    has_terminals = True

    def __init__(self, env: gym.Env[Any, Any], name: str):
        self.name, self._env = name, env
        obs_space, act_space = env.observation_space, env.action_space
        for role, space in (("observation", obs_space), ("action", act_space)):
            if not isinstance(space, gym.spaces.Box):
                raise SettingError(
                    f"{setting('task')} {name!r}: its {role} space is {space}; accepted: gymnasium "
                    "Box spaces"
                )
        assert isinstance(obs_space, gym.spaces.Box) and isinstance(act_space, gym.spaces.Box)
        low, high = np.asarray(act_space.low, np.float64), np.asarray(act_space.high, np.float64)
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
            raise SettingError(
                f"{setting('task')} {name!r}: action bounds must be finite, got {act_space}"
            )
        self._low, self._high = low.ravel(), high.ravel()
        self._set_spaces(int(np.prod(obs_space.shape)), int(np.prod(act_space.shape)))
        self._action_shape = act_space.shape
        self.episode_length = _time_limit(env, name)
        unwrapped = env.unwrapped
        model, data = getattr(unwrapped, "model", None), getattr(unwrapped, "data", None)
        if isinstance(model, mujoco.MjModel) and isinstance(data, mujoco.MjData):
            self.clip_source = "state"
            self._model, self._data = model, data
            self._camera = _tracking_camera(unwrapped)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self._env.reset(seed=seed, options=options)
        return _flat(obs), {"success": _success(info)}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = np.clip(np.asarray(action, np.float64).ravel(), -1.0, 1.0)
        scaled = self._low + (action + 1.0) * 0.5 * (self._high - self._low)
        dtype = self._env.action_space.dtype
        obs, reward, terminated, truncated, info = self._env.step(
            scaled.reshape(self._action_shape).astype(dtype)
        )
        return (
            _flat(obs),
            float(reward),
            bool(terminated),
            bool(truncated),
            {"success": _success(info)},
        )

    # ---- clips: saved MuJoCo state, or frames recorded while playing ----------------------
    def get_state(self) -> np.ndarray:
        if self.clip_source == "state":
            return super().get_state()
        return self._recorded_frame()

    def set_state(self, state: np.ndarray) -> None:
        if self.clip_source == "state":
            super().set_state(state)
        else:
            raise RuntimeError(f"task {self.name!r} records frames; it cannot restore a state")

    def render_frame(self, width: int = 128, height: int = 128) -> np.ndarray:
        if self.clip_source == "state":
            return super().render_frame(width, height)
        return _resize(self._recorded_frame(), width, height)

    def render_states(
        self, states: np.ndarray, context: int | None = None, width: int = 128, height: int = 128
    ) -> np.ndarray:
        if self.clip_source == "state":
            return super().render_states(states, context, width, height)
        return np.stack([_resize(frame, width, height) for frame in states])

    def check_clips(self) -> None:
        mode = getattr(self._env, "render_mode", None)
        if self.clip_source == "state" or mode == "rgb_array":
            return
        env_id = self.name.removeprefix("gym:") if self.name.startswith("gym:") else "..."
        raise SettingError(
            f"{setting('task')} {self.name!r} cannot show clips: it has no MuJoCo state, so its "
            f"clips are its render() frames, and it was made with render_mode={mode!r}; give a "
            "module.path:factory task whose function makes it with render_mode='rgb_array', "
            f"e.g. def make(): return gymnasium.make({env_id!r}, render_mode='rgb_array')"
        )

    def use_fast_rendering(self) -> None:
        if self.clip_source == "state":
            super().use_fast_rendering()

    def _recorded_frame(self) -> np.ndarray:
        frame = self._env.render()
        if not isinstance(frame, np.ndarray) or frame.ndim != 3:
            raise SettingError(
                f"{setting('task')} {self.name!r} has no MuJoCo state and its render() gave "
                f"{type(frame).__name__}: for clips, make the environment with "
                "render_mode='rgb_array'"
            )
        stride = max(1, -(-max(frame.shape[:2]) // FRAME_SIDE))  # ceil: at most FRAME_SIDE
        return np.ascontiguousarray(frame[::stride, ::stride, :3], np.uint8)

    def close(self) -> None:
        super().close()
        self._env.close()


def _time_limit(env: gym.Env[Any, Any], name: str) -> int:
    limit = env.spec.max_episode_steps if env.spec is not None else None
    if limit is None:
        limit = getattr(env, "max_episode_steps", None) or getattr(env, "_max_episode_steps", None)
    if limit is None:  # an environment that ends its episodes itself (seqrank's own tasks)
        limit = getattr(env.unwrapped, "max_episode_steps", None)
    if not limit:
        raise SettingError(
            f"{setting('task')} {name!r} has no time limit; wrap it in "
            "gymnasium.wrappers.TimeLimit or register it with max_episode_steps"
        )
    return int(limit)


def _tracking_camera(unwrapped: Any) -> mujoco.MjvCamera:
    """Gymnasium's own camera settings for the task, following the robot's root body."""
    renderer = getattr(unwrapped, "mujoco_renderer", None)
    settings = dict(getattr(renderer, "default_cam_config", None) or {})
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
    camera.trackbodyid = int(settings.pop("trackbodyid", 1))
    camera.distance = float(settings.pop("distance", 3.0))
    camera.elevation = float(settings.pop("elevation", -20.0))
    camera.azimuth = float(settings.pop("azimuth", 90.0))
    return camera


def _flat(obs: Any) -> np.ndarray:
    return np.asarray(obs, np.float32).ravel()


def _success(info: dict[str, Any]) -> bool:
    return bool(info.get("success", info.get("is_success", False)))


def _resize(frame: np.ndarray, width: int, height: int) -> np.ndarray:
    """Nearest-neighbour resize: recorded frames are small and clips are re-encoded anyway."""
    rows = np.arange(height) * frame.shape[0] // height
    cols = np.arange(width) * frame.shape[1] // width
    return frame[rows][:, cols]
