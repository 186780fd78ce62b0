"""What `PreferenceFeedback` is made of, from its first argument and its teacher: the
task's environments, the run config, and who answers."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
from stable_baselines3.common.env_util import is_wrapped
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

from seqrank.config import TrainConfig
from seqrank.envs import SimEnv, canonical_task, make_env
from seqrank.envs.gym_env import GymEnv
from seqrank.errors import SettingError, setting
from seqrank.feedback.session import FeedbackSource
from seqrank.sb3.envs import action_dim, observation_dim
from seqrank.training.feedback_parts import teacher_source

GYM_PRESETS = "gym:Pendulum-v1"  # whose presets an environment object's feedback starts from


@dataclass
class Task:
    """The environment to learn in: seqrank `SimEnv`s (a task name or a Gymnasium env with
    a Box action space), or a VecEnv: the user's, or one made of a Gymnasium env with a
    Discrete action space (`sims` None: no per-episode seeds or physics states)."""

    name: str
    preset_task: str
    sims: list[SimEnv] | None
    venv: VecEnv | None
    obs_dim: int
    act_dim: int
    episode_length: int | None
    has_terminals: bool


def describe_task(env: Any, n_envs: int, seed: int) -> Task:
    """The environments of `env` (checked by `task_names` already)."""
    name, preset = task_names(env)
    if isinstance(env, str):
        return _of_sims(name, preset, [make_env(env, seed) for _ in range(n_envs)])
    if not isinstance(env, VecEnv | SimEnv) and isinstance(env.action_space, gym.spaces.Discrete):
        env = _vec_env_of_one(env)  # its actions need no rescaling: as SB3 itself takes it
    if isinstance(env, VecEnv):  # used as it is
        obs, act = observation_dim(env.observation_space), action_dim(env.action_space)
        return Task(name, preset, None, env, obs, act, None, True)
    sim = env if isinstance(env, SimEnv) else GymEnv(env, name)
    return _of_sims(name, preset, [sim])


def _vec_env_of_one(env: gym.Env[Any, Any]) -> DummyVecEnv:
    """A Gymnasium env in a VecEnv of one, with SB3's Monitor (the true episode return in
    `info["episode"]`) unless it has one: as SB3 wraps an Env it is given."""
    monitored = env if is_wrapped(env, Monitor) else Monitor(env)
    return DummyVecEnv([lambda: monitored])


def _of_sims(name: str, preset_task: str, sims: list[SimEnv]) -> Task:
    first = sims[0]
    act = first.act_dim
    return Task(
        name, preset_task, sims, None, first.obs_dim, act, first.episode_length, first.has_terminals
    )


def _env_name(env: Any) -> str:
    spec = getattr(env, "spec", None)
    if spec is None and isinstance(env, VecEnv):
        spec = env.get_attr("spec")[0]
    return f"gym:{spec.id}" if spec is not None else type(env).__name__


def task_names(env: Any) -> tuple[str, str]:
    """(the name saved settings give the task, the task whose presets apply)."""
    if isinstance(env, str):
        canonical_task(env)  # a bad name: SettingError naming what is accepted
        return env, env
    if isinstance(env, VecEnv | gym.Env):
        return _env_name(env), GYM_PRESETS
    raise SettingError(
        f"{setting('env')} {env!r}; accepted: a seqrank task name (walker_walk, dmc:..., "
        "metaworld:..., gym:ID, module.path:factory), a gymnasium.Env or an SB3 VecEnv"
    )


def make_teacher(
    teacher: str | FeedbackSource | Callable[..., Any], obs_dim: int, config: TrainConfig
) -> FeedbackSource | None:
    """The source of a teacher value (a name: `config.teacher`, read with its crowd
    settings); None for `human` (the labelling page's)."""
    if isinstance(teacher, str):
        return None if teacher == "human" else teacher_source(config)
    if hasattr(teacher, "ask_session"):
        return teacher  # type: ignore[return-value]
    if callable(teacher):
        from seqrank.api import JudgeSource

        return JudgeSource(teacher, obs_dim)
    raise SettingError(
        f"{setting('teacher')} {teacher!r}; accepted: a teacher value (oracle, a preset with "
        "knobs, replay:FILE, human), a FeedbackSource, or a judge(first, second) function"
    )
