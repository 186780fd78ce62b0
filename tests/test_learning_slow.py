"""A learned-reward agent clearly beats random actions (slow: minutes on 2 cores)."""

from __future__ import annotations

import numpy as np
import pytest

from seqrank.config import resolve_config
from seqrank.envs import make_env
from seqrank.loop import Trainer, episode_seed
from seqrank.runs import RunDir


def random_return(task: str, episodes: int) -> float:
    env = make_env(task)
    rng = np.random.default_rng(0)
    totals = []
    for i in range(episodes):
        env.reset(seed=episode_seed(0, 1, 0, i))
        total, done = 0.0, False
        while not done:
            _, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, env.act_dim))
            total, done = total + reward, terminated or truncated
        totals.append(total)
    env.close()
    return float(np.mean(totals))


@pytest.mark.slow
def test_sequential_preferences_teach_cartpole_to_balance(tmp_path):
    task = "dmc:cartpole_balance"
    config = resolve_config(
        task, "small",
        dict(steps=16_000, seed_steps=1_000, unsup_steps=2_000, feedback_frequency=2_000,
             max_feedback=60, reward_batch=10, eval_every=8_000, eval_episodes=5,
             checkpoint_every=100_000, device="cpu", scheme="sequential"),
    )
    summary = Trainer(config, RunDir.create(tmp_path / "run", config, "cpu")).train()
    baseline = random_return(task, 5)
    assert summary["asked"] == 60
    assert summary["final_eval_return"] > max(2 * baseline, baseline + 300), (summary, baseline)
