"""The learning scenario of `tests/sb3/test_sb3_learning.py` (and of its measurement in
`tests/learning_thresholds.md`): an SB3 agent on the line task from oracle preferences,
scored on the true reward, beside a uniformly random policy."""

from __future__ import annotations

import numpy as np
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.evaluation import evaluate_policy

from support.sb3_envs import make_line
from support.sb3_runs import SMALL_SAC, feedback

EVAL_EPISODES = 10
REWARD = dict(max_feedback=60, reward_batch=20, reward_epochs=50, segment_length=20)
SCENARIOS = {
    # agent, its options, steps, feedback settings
    "SAC": (SAC, SMALL_SAC, 2000, dict(REWARD, steps=2000)),
    "PPO": (
        PPO,
        dict(n_steps=250, batch_size=50, policy_kwargs=dict(net_arch=[32, 32])),
        5000,
        dict(REWARD, steps=5000, feedback_frequency=1000),
    ),
}


def learned_return(agent: str, seed: int) -> float:
    """Mean true return of the deterministic policy after training from preferences."""
    kind, options, steps, settings = SCENARIOS[agent]
    fb = feedback(seed=seed, **settings)
    model = kind("MlpPolicy", fb.env, seed=seed, **options)
    model.learn(steps, callback=fb)
    env = make_line()
    env.reset(seed=1000 + seed)
    mean, _ = evaluate_policy(model, env, n_eval_episodes=EVAL_EPISODES, deterministic=True)
    return float(mean)


def random_return(seed: int) -> float:
    env = make_line()
    rng = np.random.default_rng(seed)
    total = 0.0
    for episode in range(EVAL_EPISODES):
        env.reset(seed=1000 + seed + episode)
        done = False
        while not done:
            _, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 1))
            total += float(reward)
            done = terminated or truncated
    return total / EVAL_EPISODES
