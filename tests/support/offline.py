"""Small offline datasets for the offline learner's tests: random play on the line task
(`support.sb3_envs`), in memory or written as a Minari dataset."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from seqrank.envs import make_env
from seqrank.offline.dataset import OfflineDataset
from seqrank.offline.minari_write import PlayedEpisode, save_episodes

LINE = "support.sb3_envs:make_line"  # 50-step episodes, reward minus the distance


def play_random(task: str, episodes: int, seed: int) -> list[PlayedEpisode]:
    """Uniform random actions, each episode reset with its own seed."""
    env = make_env(task, seed)
    rng = np.random.default_rng(seed)
    played = []
    try:
        for _ in range(episodes):
            reset_seed = int(rng.integers(2**31))
            obs, _ = env.reset(seed=reset_seed)
            rows, actions, rewards, terminated, truncated = [obs], [], [], [], []
            done = False
            while not done:
                action = rng.uniform(-1.0, 1.0, env.act_dim).astype(np.float32)
                obs, reward, term, trunc, _ = env.step(action)
                rows.append(obs)
                actions.append(action)
                rewards.append(reward)
                terminated.append(term)
                truncated.append(trunc)
                done = term or trunc
            played.append(
                PlayedEpisode(
                    np.array(rows, np.float32),
                    np.array(actions, np.float32),
                    np.array(rewards, np.float32),
                    np.array(terminated, bool),
                    np.array(truncated, bool),
                    None,
                    reset_seed,
                )
            )
    finally:
        env.close()
    return played


def in_memory(played: list[PlayedEpisode], task: str = LINE) -> OfflineDataset:
    lengths = [len(e.actions) for e in played]
    return OfflineDataset(
        task=task,
        observations=np.concatenate([e.observations[:-1] for e in played]),
        actions=np.concatenate([e.actions for e in played]),
        rewards=np.concatenate([e.rewards for e in played]).astype(np.float32),
        next_observations=np.concatenate([e.observations[1:] for e in played]),
        terminations=np.concatenate([e.terminations for e in played]),
        truncations=np.concatenate([e.truncations for e in played]),
        starts=np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64),
    )


def write_dataset(
    path: Path, episodes: int = 20, seed: int = 0, task: str = LINE, extra_obs: int = 0
) -> Path:
    """Random play on `task` as a Minari dataset at `path`; `extra_obs` zero columns are
    appended to the observations (a dataset whose sizes do not fit its task)."""
    played = play_random(task, episodes, seed)
    if extra_obs:
        played = [
            PlayedEpisode(
                np.pad(e.observations, ((0, 0), (0, extra_obs))),
                e.actions,
                e.rewards,
                e.terminations,
                e.truncations,
                e.success,
                e.seed,
            )
            for e in played
        ]
    provenance = {"task": task, "source": "random", "episodes": episodes, "seed": seed}
    save_episodes(played, str(path), task, provenance, "random play (test)")
    return path
