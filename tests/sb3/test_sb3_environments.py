"""Which environment the agent is made on: `feedback.env` (or a wrapper of it) and nothing
else, said at the start of `learn`; a plain Gymnasium env with a discrete action space
taken as SB3 takes it (a VecEnv of one), for DQN and A2C alike."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import A2C, DQN, PPO, SAC
from stable_baselines3.common.vec_env import VecNormalize

from seqrank.sb3 import PreferenceFeedback
from support.sb3_envs import make_line
from support.sb3_runs import LINE, TINY, feedback, small_sac

NOT_ON_FEEDBACK_ENV = r"^the agent's environment is not feedback\.env: make it on feedback\.env"


@pytest.mark.parametrize("agent", [SAC, PPO])
def test_an_agent_made_on_the_users_own_env_is_told_to_use_feedback_env(agent):
    taught = feedback()
    options = small_sac() if agent is SAC else dict(n_steps=64, batch_size=32)
    model = agent("MlpPolicy", make_line(), seed=0, **options)
    with pytest.raises(ValueError, match=NOT_ON_FEEDBACK_ENV) as refused:
        model.learn(50, callback=taught)
    assert f"{agent.__name__}('MlpPolicy', feedback.env" in str(refused.value)
    assert "\n" not in str(refused.value) and model.num_timesteps == 0


def test_an_agent_on_a_wrapper_of_feedback_env_learns():
    taught = feedback()
    model = SAC("MlpPolicy", VecNormalize(taught.env), seed=0, **small_sac())
    model.learn(50, callback=taught)
    assert model.num_timesteps == 50


CARTPOLE = {**TINY, "unsup_steps": 0, "seed_steps": 100, "segment_length": 10}


@pytest.mark.parametrize("agent", [DQN, A2C])
def test_a_plain_discrete_gymnasium_env_is_taken_as_a_vec_env_of_one(agent):
    taught = PreferenceFeedback(gym.make("CartPole-v1"), **CARTPOLE)
    assert taught.env.num_envs == 1 and taught.state.task.act_dim == 2
    options = dict(learning_starts=50, batch_size=32) if agent is DQN else dict(n_steps=20)
    model = agent("MlpPolicy", taught.env, seed=0, **options)
    model.learn(200, callback=taught)
    assert taught.run.counters.sessions == 1 and len(taught.labels) >= 10
    assert taught.reward(np.zeros((2, 4)), np.array([0, 1])).shape == (2,)


def test_the_impossible_budget_hint_names_every_agent_that_does_not_pre_train():
    settings = {k: v for k, v in TINY.items() if k != "unsup_steps"}
    with pytest.raises(ValueError, match="impossible budget") as refused:
        PreferenceFeedback(LINE, **{**settings, "steps": 1500})
    hint = str(refused.value)
    assert all(name in hint for name in ("SAC", "TD3", "DQN", "PPO", "A2C", "pretrain=False"))
    fits = PreferenceFeedback(LINE, **{**settings, "steps": 1500}, pretrain=False)
    assert fits.config.unsup_steps == 0
