"""The agent's side of the environment: `feedback.env`, a VecEnv whose reward is the
learned reward. The true reward goes into each step's `info["true_reward"]` (for the
scripted teacher, evaluation and logging) and never into the reward the agent learns from.

A seqrank task name (or a Gymnasium env) becomes a `DummyVecEnv` of seqrank `SimEnv`s whose
episodes are seeded by the run seed and their number, as in seqrank's own loop, so a run
stopped at an episode end and continued replays the same episodes. A VecEnv the user made
is wrapped as it is.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvStepReturn

from seqrank.envs import SimEnv
from seqrank.envs.block import one_hot
from seqrank.envs.recorder import EpisodeRecorder
from seqrank.episodes import EpisodeStore
from seqrank.errors import SettingError, setting
from seqrank.training.state import episode_seed

# (observations (N, obs_dim), canonical actions (N, act_dim)) -> learned rewards (N,)
BatchReward = Callable[[np.ndarray, np.ndarray], np.ndarray]


class SeededEpisodes(gym.Wrapper[np.ndarray, Any, np.ndarray, Any]):
    """Episode k of env i starts from `episode_seed(run_seed, 0, k * n_envs + i)` whatever
    seed the VecEnv passes (with one env: seqrank's own loop's seeds). The action an agent
    gives is the task's: in [-1, 1], or for a discrete task (block:place) the index of a
    choice, given to the task as a one-hot."""

    def __init__(self, env: SimEnv, run_seed: int, index: int, n_envs: int):
        super().__init__(env)
        self.sim, self.run_seed, self.index, self.n_envs = env, run_seed, index, n_envs
        self.next_episode = 0  # the number of the episode the next reset starts
        if env.discrete:
            self.action_space = gym.spaces.Discrete(env.act_dim)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        number = self.next_episode * self.n_envs + self.index
        self.next_episode += 1
        return self.env.reset(seed=episode_seed(self.run_seed, 0, number), options=options)

    def step(self, action: Any) -> Any:
        if self.sim.discrete:
            action = one_hot(int(np.asarray(action).reshape(-1)[0]))
        return self.env.step(action)


def task_vec_env(sims: list[SimEnv], run_seed: int) -> DummyVecEnv:
    """A DummyVecEnv of the task's envs; Monitor puts the true episode return into
    `info["episode"]` (SB3's `rollout/ep_rew_mean`)."""

    def maker(i: int) -> Callable[[], gym.Env[Any, Any]]:
        return lambda: Monitor(SeededEpisodes(sims[i], run_seed, i, len(sims)))

    return DummyVecEnv([maker(i) for i in range(len(sims))])


def canonical_actions(space: gym.spaces.Space[Any], actions: np.ndarray) -> np.ndarray:
    """Actions as the reward model reads them: a Box's scaled to [-1, 1] (what SB3's
    off-policy agents store), a Discrete's one-hot. (N, act_dim) float32."""
    if isinstance(space, gym.spaces.Discrete):
        indices = np.asarray(actions).reshape(-1).astype(np.int64)
        return np.eye(int(space.n), dtype=np.float32)[indices]
    assert isinstance(space, gym.spaces.Box)
    low, high = space.low.reshape(-1), space.high.reshape(-1)
    flat = np.asarray(actions, np.float64).reshape(len(actions), -1)
    if np.all(np.isfinite(low)) and np.all(np.isfinite(high)):
        flat = 2.0 * (flat - low) / (high - low) - 1.0
    return np.clip(flat, -1.0, 1.0).astype(np.float32)


def reward_batch(
    obs_space: gym.spaces.Space[Any], act_space: gym.spaces.Space[Any], obs: Any, actions: Any
) -> tuple[np.ndarray, np.ndarray]:
    """(N, obs_dim) observations and (N, act_dim) canonical actions of a batch in the
    spaces' shapes (actions (N,) of a one-number Box too; a Discrete's indices (N,) or
    (N, 1)); a ValueError naming the expected and received shapes otherwise."""
    obs, actions = np.asarray(obs), np.asarray(actions)
    obs_dim, act_dim = observation_dim(obs_space), action_dim(act_space)
    discrete = isinstance(act_space, gym.spaces.Discrete)
    if discrete:
        act_text, act_shapes = f"(N,), indices from 0 to {act_dim - 1}", {(), (1,)}
    else:
        act_text, act_shapes = f"(N, {act_dim})", {(act_dim,), tuple(act_space.shape or ())}
        act_shapes |= {()} if act_dim == 1 else set()
    expected = f"reward() takes a batch: observations (N, {obs_dim}) and actions {act_text}"
    fits = obs.ndim >= 1 and actions.ndim >= 1 and len(obs) == len(actions)
    fits = fits and obs.shape[1:] in {(obs_dim,), tuple(obs_space.shape or ())}
    if not fits or actions.shape[1:] not in act_shapes:
        raise ValueError(f"{expected}; got observations {obs.shape} and actions {actions.shape}")
    for name, values in (("observations", obs), ("actions", actions)):
        if values.dtype.kind not in "biuf":
            raise ValueError(f"{expected}; got {name} of {values.dtype}, not numbers")
    if discrete:
        flat = actions.reshape(-1)
        whole = np.all(np.isfinite(flat)) and np.all(flat == np.round(flat))
        if not (whole and np.all((flat >= 0) & (flat < act_dim))):
            raise ValueError(f"{expected}; got actions {flat}")
    flat_obs = obs.reshape(len(obs), -1).astype(np.float32)
    return flat_obs, canonical_actions(act_space, actions)


def action_dim(space: gym.spaces.Space[Any]) -> int:
    if isinstance(space, gym.spaces.Discrete):
        return int(space.n)
    if isinstance(space, gym.spaces.Box):
        return int(np.prod(space.shape))
    raise SettingError(
        f"{setting('env')}: its action space is {space}; accepted: gymnasium Box or Discrete"
    )


def observation_dim(space: gym.spaces.Space[Any]) -> int:
    if not isinstance(space, gym.spaces.Box):
        raise SettingError(
            f"{setting('env')}: its observation space is {space}; accepted: a gymnasium Box"
        )
    return int(np.prod(space.shape))


class PreferenceVecEnv(VecEnvWrapper):
    """Records every episode into the episode store that sessions cut segments from, and
    gives the agent `learned(obs, action)` (0 before the first reward model)."""

    def __init__(
        self,
        venv: VecEnv,
        episodes: EpisodeStore,
        learned: BatchReward,
        sims: list[SimEnv] | None,
        record_states: bool,
    ):
        super().__init__(venv)
        self.episodes, self.learned, self.sims = episodes, learned, sims
        self.recorders = [EpisodeRecorder(record_states) for _ in range(venv.num_envs)]
        self.contexts: list[int | None] = [None] * venv.num_envs
        # each environment's steps since its episode began (0 at an episode end: a saved
        # run continues exactly only from there)
        self.steps_into_episodes = [0] * venv.num_envs
        self._obs: np.ndarray | None = None
        self._actions: np.ndarray | None = None

    def reset(self) -> Any:
        obs = self.venv.reset()
        self._obs = self._flat(obs)
        self.recorders = [EpisodeRecorder(r.record_states) for r in self.recorders]
        self.contexts = [info.get("task_index") for info in self.venv.reset_infos]
        self.steps_into_episodes = [0] * self.num_envs
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = canonical_actions(self.action_space, actions)
        if self.sims is not None:
            for recorder, sim in zip(self.recorders, self.sims, strict=True):
                recorder.before_step(sim)
        self.venv.step_async(actions)

    def step_wait(self) -> VecEnvStepReturn:
        assert self._obs is not None and self._actions is not None, "reset first"
        obs, true_rewards, dones, infos = self.venv.step_wait()
        learned = self.learned(self._obs, self._actions).astype(np.float32)
        for i, info in enumerate(infos):
            info["true_reward"] = float(true_rewards[i])
            self.recorders[i].add(self._obs[i], self._actions[i], float(true_rewards[i]))
            self.steps_into_episodes[i] = 0 if dones[i] else self.steps_into_episodes[i] + 1
            if dones[i]:
                self.episodes.add(self.recorders[i].finish(self.contexts[i]))
                self.contexts[i] = self.venv.reset_infos[i].get("task_index")
        self._obs = self._flat(obs)
        return obs, learned, dones, infos

    @staticmethod
    def _flat(obs: Any) -> np.ndarray:
        return np.asarray(obs, np.float32).reshape(len(obs), -1)
