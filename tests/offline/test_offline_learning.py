"""IQL learns from a fixed dataset: on random play of the line task (a point that should
reach a target, reward minus the distance: `support.sb3_envs`), its policy ends far
closer to the target than the random actions that made the dataset.

The margins sit well inside the distribution measured over 16 seeds
(`tests/learning_thresholds.md`); the test asserts on the mean of seeds 0-2, each
scored against random actions on the same evaluation episodes."""

from __future__ import annotations

import numpy as np
import torch

import seqrank
from seqrank.envs import make_env
from seqrank.training.evaluation import evaluate_policy
from seqrank.training.state import episode_seed
from support.offline import LINE, write_dataset

SEEDS = (0, 1, 2)
SMALL = {"steps": 1000, "eval_every": 1000, "eval_episodes": 10, "hidden": 64, "batch": 128,
         "device": "cpu"}  # fmt: skip


class RandomActions:
    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)

    def act(self, obs: np.ndarray, deterministic: bool, generator: torch.Generator) -> np.ndarray:
        return self.rng.uniform(-1.0, 1.0, 1).astype(np.float32)


def random_return(seed: int) -> float:
    """Random actions on the episodes the run's (first) evaluation played."""
    seeds = [episode_seed(seed, 1, 0, i) for i in range(SMALL["eval_episodes"])]
    env = make_env(LINE, seed)
    try:
        return float(
            np.mean(evaluate_policy(RandomActions(seed), env, seeds, torch.Generator()).returns)
        )
    finally:
        env.close()


def test_iql_on_random_play_ends_far_closer_to_the_target_than_random_actions(tmp_path):
    learned, random = [], []
    for seed in SEEDS:
        data = write_dataset(tmp_path / f"line{seed}", episodes=20, seed=seed)
        summary = seqrank.offline_train(data, tmp_path / f"run{seed}", seed=seed, **SMALL)
        learned.append(summary["final_eval_return"])
        random.append(random_return(seed))
    assert np.mean(learned) > -12.0, (learned, random)
    assert np.mean(learned) - np.mean(random) > 12.0, (learned, random)
