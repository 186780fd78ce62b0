"""One factory for DMControl and Meta-World v3 tasks, with gymnasium semantics (and, through
`gym_env.py`, any Gymnasium environment: `gym:ID` or a user's `module.path:factory`).

`make_env("walker_walk")`, `make_env("dmc:cartpole_swingup")`, `make_env("door-open")`,
`make_env("metaworld:door-open-v3")`. Every environment:

- returns flattened float32 observations and takes actions in [-1, 1];
- puts `success` in every step's info (always False on DMControl, which has none);
- has no true terminals (the Gymnasium tasks do): episodes end by time limit
  (`truncated`), DMC 1 000 steps, Meta-World 500;
- is reseeded at every `reset(seed=...)`, so an episode is a function of its seed (this is
  what lets a killed run resume exactly); Meta-World draws its task (goal) from the 50 MT1
  tasks with that seed and reports it as `info["task_index"]`;
- renders headless frames (MuJoCo with EGL unless MUJOCO_GL says otherwise) and saves /
  restores the full physics state of any step, so a segment can be re-rendered later.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # headless; must be set before MuJoCo loads GL

from typing import Any

import mujoco
import numpy as np

from seqrank.envs.base import SimEnv
from seqrank.errors import SettingError, setting

DMC_PAPER_TASKS = ("walker_walk", "cheetah_run", "quadruped_walk", "humanoid_walk", "hopper_hop")
METAWORLD_PAPER_TASKS = (
    "button-press",
    "door-open",
    "drawer-open",
    "sweep-into",
    "window-open",
    "hammer",
)
PAPER_TASKS = DMC_PAPER_TASKS + METAWORLD_PAPER_TASKS


BLOCK_TASKS = ("place",)


SUITES = ("dmc", "metaworld", "block", "gym")


def same_task(first: str, second: str) -> bool:
    """Whether two names are one task (`walker_walk` and `dmc:walker_walk`, `window-open`
    and `metaworld:window-open-v3`); names that are no task are the same only as written."""
    try:
        return canonical_task(first) == canonical_task(second)
    except SettingError:
        return first == second


def canonical_task(name: str) -> tuple[str, str]:
    """("dmc", "walker_walk"), ("metaworld", "door-open-v3"), ("block", "place"),
    ("gym", "Hopper-v5") or ("custom", "my_pkg.envs:make") (a user's factory)."""
    suite_name, _, task = name.partition(":") if ":" in name else ("", "", name)
    if suite_name == "block" and task in BLOCK_TASKS:
        return "block", task
    if suite_name == "gym":
        from seqrank.envs.gym_env import check_gym_id

        check_gym_id(task)
        return "gym", task
    if suite_name and suite_name not in SUITES and task:
        from seqrank.envs.gym_env import load_factory

        load_factory(name)  # raises naming what is missing
        return "custom", name
    if suite_name in ("", "dmc") and task in _dmc_tasks():
        return "dmc", task
    mw_task = task if task.endswith("-v3") else f"{task}-v3"
    if suite_name in ("", "metaworld") and mw_task in _metaworld_tasks():
        return "metaworld", mw_task
    raise SettingError(
        f"unknown {setting('task')} {name!r}; accepted: {', '.join(PAPER_TASKS)}, any DMControl "
        "domain_task (e.g. dmc:cartpole_swingup) or Meta-World v3 MT1 task "
        "(e.g. metaworld:reach-v3), block:place (the tabletop block-placing task), "
        "gym:ID (a registered Gymnasium environment, e.g. gym:Hopper-v5) or "
        "module.path:factory (your own function returning a gymnasium.Env)"
    )


def _dmc_tasks() -> set[str]:
    from dm_control import suite

    return {f"{domain}_{task}" for domain, task in suite.ALL_TASKS}


def _metaworld_tasks() -> set[str]:
    import metaworld

    return set(metaworld.MT1.ENV_NAMES)


def make_env(name: str, seed: int = 0) -> SimEnv:
    """The environment of task `name` (as `--task` accepts it), seeded with `seed`.

    A gymnasium.Env with flattened float32 observations and actions in [-1, 1], that
    renders headless frames and saves and restores its physics state (the module says
    more); `obs_dim` and `act_dim` give the sizes.

    Args:
        name: walker_walk or another DMControl `domain_task` (dmc:cartpole_swingup), a
            Meta-World v3 task (door-open, metaworld:reach-v3), block:place, gym:ID (a
            registered Gymnasium environment) or module.path:factory (your function
            returning a gymnasium.Env); a SettingError (a ValueError) lists them.
        seed: seeds the simulator (gym: and custom tasks are seeded at reset only); an
            episode begun by `reset(seed=...)` depends on that seed alone.

    Returns:
        The environment, a `SimEnv`.

    Examples:
        >>> import seqrank
        >>> env = seqrank.make_env("dmc:cartpole_swingup")
        >>> env.obs_dim, env.act_dim, env.episode_length
        (5, 1, 1000)
        >>> obs, info = env.reset(seed=0)
        >>> obs.shape, obs.dtype
        ((5,), dtype('float32'))
    """
    suite_name, task = canonical_task(name)
    if suite_name == "dmc":
        return DMCEnv(task, seed)
    if suite_name == "block":
        from seqrank.envs.block import BlockPlaceEnv

        return BlockPlaceEnv(seed)
    if suite_name in ("gym", "custom"):
        import gymnasium

        from seqrank.envs.gym_env import GymEnv, load_factory

        env = gymnasium.make(task) if suite_name == "gym" else load_factory(task)()
        return GymEnv(env, name)  # seeded at every reset(seed=...), like the others
    return MetaWorldEnv(task, seed)


class DMCEnv(SimEnv):
    def __init__(self, task: str, seed: int = 0):
        from dm_control import suite

        domain, _, task_name = task.partition("_")
        if (domain, task_name) not in suite.ALL_TASKS:  # e.g. ball_in_cup_catch
            domain, task_name = next((d, t) for d, t in suite.ALL_TASKS if f"{d}_{t}" == task)
        self.name = f"dmc:{task}"
        self._env = suite.load(domain, task_name, task_kwargs={"random": seed})
        spec = self._env.action_spec()
        self._low, self._high = spec.minimum.astype(np.float64), spec.maximum.astype(np.float64)
        obs_dim = sum(int(np.prod(s.shape)) for s in self._env.observation_spec().values())
        self._set_spaces(obs_dim, spec.shape[0])
        self._model = self._env.physics.model.ptr
        self._data = self._env.physics.data.ptr
        self.episode_length = round(self._env._step_limit)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if seed is not None:
            self._env.task._random = np.random.RandomState(seed)
        step = self._env.reset()
        return _flatten(step.observation), {"success": False}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = np.clip(np.asarray(action, np.float64), -1.0, 1.0)
        step = self._env.step(self._low + (action + 1.0) * 0.5 * (self._high - self._low))
        reward = float(step.reward or 0.0)
        return _flatten(step.observation), reward, False, bool(step.last()), {"success": False}


def _flatten(observation: dict[str, Any]) -> np.ndarray:
    return np.concatenate([np.asarray(v, np.float32).ravel() for v in observation.values()])


def _patch_metaworld_mocap_welds() -> None:
    """Meta-World 3.0.0 writes 11 weld parameters where MuJoCo >= 3.4 has 12 slots.

    Write the same 11 values into the first 11 slots (the 12th, torque scale, keeps
    MuJoCo's default). Without this, every Meta-World env fails at construction.
    """
    from metaworld.sawyer_xyz_env import SawyerMocapBase

    def reset_mocap_welds(self: Any) -> None:
        if self.model.nmocap > 0 and self.model.eq_data is not None:
            for i in range(self.model.eq_data.shape[0]):
                if self.model.eq_type[i] == mujoco.mjtEq.mjEQ_WELD:
                    self.model.eq_data[i, :11] = [0, 0, 0, 0, 0, 0, -1, 0, 0, 0, 5]

    SawyerMocapBase.reset_mocap_welds = reset_mocap_welds  # type: ignore[method-assign]


class MetaWorldEnv(SimEnv):
    _camera = "corner"
    _flip = True  # Meta-World's corner cameras render upside down

    def __init__(self, task: str, seed: int = 0):
        import metaworld

        _patch_metaworld_mocap_welds()
        self.name = f"metaworld:{task}"
        benchmark = metaworld.MT1(task, seed=seed)
        self._tasks = benchmark.train_tasks
        self._env = benchmark.train_classes[task]()
        self._env.set_task(self._tasks[0])
        self._task_index = 0
        self.episode_length = int(self._env.max_path_length)
        spaces = (self._env.observation_space, self._env.action_space)
        self._set_spaces(*(len(space.low) for space in spaces))  # type: ignore[attr-defined]
        self._model, self._data = self._env.model, self._env.data

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        task_rng = np.random.default_rng(seed)
        self._task_index = int(task_rng.integers(len(self._tasks)))
        self._env.set_task(self._tasks[self._task_index])
        obs, _ = self._env.reset()
        mujoco.mj_forward(self._model, self._data)  # reset leaves derived quantities stale
        self._place_goal_sites()
        return obs.astype(np.float32), {"success": False, "task_index": self._task_index}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = np.clip(np.asarray(action, np.float64), -1.0, 1.0)
        obs, reward, _, truncated, info = self._env.step(action)
        info = {"success": bool(info.get("success", False)), "task_index": self._task_index}
        return obs.astype(np.float32), float(reward), False, bool(truncated), info

    def set_state(self, state: np.ndarray) -> None:
        super().set_state(state)
        self._place_goal_sites()

    def _place_goal_sites(self) -> None:
        """Put goal markers where step() puts them, so every frame shows them alike."""
        for site in self._env._target_site_config:
            self._env._set_pos_site(*site)

    def restore_context(self, context: int | None) -> None:
        if context is not None and context != self._task_index:
            self._task_index = context
            self._env.set_task(self._tasks[context])
            self._env.reset()
