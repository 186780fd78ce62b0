"""Acting and storing: the warm-up's random actions, then the agent's; every transition
into the replay buffer (with its learned reward once there is a reward model) and every
episode into the episode store that feedback segments are cut from."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from seqrank.agents.protocol import Agent
from seqrank.buffer import ReplayBuffer, RewardFn
from seqrank.envs.base import SimEnv
from seqrank.envs.recorder import EpisodeRecorder
from seqrank.episodes import EpisodeStore
from seqrank.training.state import Counters, episode_seed


class Collector:
    """With `lookahead` (the fast path), the next action is computed before the agent's
    update is launched, so the simulator steps on the host while the GPU updates (the
    action is then one update stale)."""

    def __init__(
        self,
        env: SimEnv,
        agent: Agent,
        replay: ReplayBuffer,
        episodes: EpisodeStore,
        record_states: bool,
        seed_steps: int,
        rng: np.random.Generator,
        generator: torch.Generator,
        lookahead: bool,
        total_steps: int,
    ):
        self.env, self.agent, self.replay, self.episodes = env, agent, replay, episodes
        self.recorder = EpisodeRecorder(record_states)
        self.seed_steps, self.rng, self.generator = seed_steps, rng, generator
        self.lookahead, self.total_steps = lookahead, total_steps
        self.next_action: np.ndarray | None = None
        self._obs: np.ndarray | None = None
        self._context: int | None = None

    def start_episode(self, run_seed: int, counters: Counters) -> None:
        obs, info = self.env.reset(seed=episode_seed(run_seed, 0, counters.episode))
        self._obs, self._context = obs, info.get("task_index")

    def act(self, step: int) -> np.ndarray:
        """Uniform random actions during the warm-up (`seed_steps`), then the policy's."""
        if step < self.seed_steps:
            return self.rng.uniform(-1.0, 1.0, self.env.act_dim).astype(np.float32)
        action: np.ndarray = self.agent.act(self._obs, False, self.generator)
        return action

    def step(self, run_seed: int, counters: Counters, reward_fn: RewardFn | None) -> bool:
        """One environment step; True when it ended an episode (a new one has begun)."""
        assert self._obs is not None, "start_episode first"
        action = self.act(counters.step) if self.next_action is None else self.next_action
        self.recorder.before_step(self.env)
        next_obs, reward, terminated, truncated, _ = self.env.step(action)
        action, obs, true_reward = self.env.canonical_action(action), self._obs, float(reward)
        self.replay.add_transition(obs, action, true_reward, next_obs, terminated, reward_fn)
        self.recorder.add(obs, action, true_reward)
        self._obs, counters.step = next_obs, counters.step + 1
        episode_over = bool(terminated or truncated)
        if episode_over:
            self.episodes.add(self.recorder.finish(self._context))
            counters.episode += 1
            self.start_episode(run_seed, counters)
        if self.lookahead:
            more = counters.step < self.total_steps
            self.next_action = self.act(counters.step) if more else None
        return episode_over

    def state_dict(self) -> dict[str, Any]:
        return {"next_action": self.next_action}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.next_action = state.get("next_action") if self.lookahead else None
