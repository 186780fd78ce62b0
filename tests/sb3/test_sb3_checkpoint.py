"""SB3's own savers work beside the feedback at any step: `CheckpointCallback` with
`save_replay_buffer=True` pickles the `PreferenceReplayBuffer` during pre-training and after
the sessions, and each saved buffer loads and samples as it did: the state-entropy reward
before the first session, the relabelled learned rewards after it."""

from __future__ import annotations

import numpy as np
import torch
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import CheckpointCallback

from seqrank.sb3 import PreferenceReplayBuffer
from support.sb3_runs import feedback, small_sac


def test_sb3s_checkpoint_callback_saves_the_buffer_with_its_reward_before_and_after_sessions(
    tmp_path,
):
    taught = feedback(steps=1400, max_feedback=30)  # pre-training to step 500, then a session
    model = SAC("MlpPolicy", taught.env, seed=0, **small_sac())
    saver = CheckpointCallback(save_freq=300, save_path=str(tmp_path), save_replay_buffer=True)
    model.learn(700, callback=[taught, saver])
    assert taught.run.counters.sessions == 1  # at step 500: between the two checkpoints

    during = SAC("MlpPolicy", taught.env, **small_sac())
    during.load_replay_buffer(tmp_path / "rl_model_replay_buffer_300_steps.pkl")
    saved = during.replay_buffer
    assert isinstance(saved, PreferenceReplayBuffer) and saved.entropy is not None
    assert saved.pos == 299  # SB3 saves in `on_step`, before storing the step's transition
    np.testing.assert_array_equal(saved.observations[:299], model.replay_buffer.observations[:299])
    torch.manual_seed(0)
    batch = saved.sample(16)  # the state-entropy reward, worked out here
    stored = saved.observations[:299, 0].astype(np.float64)
    queries = batch.observations.numpy().astype(np.float64)
    distances = np.linalg.norm(queries[:, None] - stored[None], axis=-1)
    kth = np.sort(distances, axis=1)[:, taught.config.knn_k]  # the query itself is at 0
    np.testing.assert_allclose(batch.rewards.numpy()[:, 0], kth / saved.entropy.stats.std, 1e-4)
    assert saved.entropy.knn_k == taught.config.knn_k

    after = SAC("MlpPolicy", taught.env, **small_sac())
    after.load_replay_buffer(tmp_path / "rl_model_replay_buffer_600_steps.pkl")
    assert after.replay_buffer.entropy is None  # pre-training ended with the session
    relabelled = after.replay_buffer.rewards[:599]
    np.testing.assert_array_equal(relabelled, model.replay_buffer.rewards[:599])
    assert np.ptp(relabelled) > 0  # the learned reward of the session at step 500
    sampled = after.replay_buffer.sample(16).rewards.numpy()[:, 0]
    assert set(sampled) <= set(relabelled[:, 0])
