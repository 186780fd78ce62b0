"""SB3's own savers work beside the feedback at any step: `CheckpointCallback` with
`save_replay_buffer=True` pickles the replay buffer during pre-training (while its batches
carry the state-entropy reward) and after the sessions, and each saved buffer loads as
SB3 made it."""

from __future__ import annotations

import numpy as np
from stable_baselines3 import SAC
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback

from support.sb3_runs import feedback, small_sac


class PretrainingBatch(BaseCallback):
    """Samples a batch at step `at` (after a checkpoint was saved), as SAC's update would."""

    def __init__(self, at: int):
        super().__init__()
        self.at, self.rewards = at, np.zeros(0)

    def _on_step(self) -> bool:
        if self.num_timesteps == self.at:
            self.rewards = self.model.replay_buffer.sample(16).rewards.numpy()
        return True


def test_sb3s_checkpoint_callback_saves_the_replay_buffer_before_and_after_sessions(tmp_path):
    taught = feedback(steps=1400, max_feedback=30)  # pre-training to step 500, then a session
    model = SAC("MlpPolicy", taught.env, seed=0, **small_sac())
    saver = CheckpointCallback(save_freq=300, save_path=str(tmp_path), save_replay_buffer=True)
    probe = PretrainingBatch(at=301)
    model.learn(700, callback=[taught, saver, probe])

    assert taught.run.counters.sessions == 1  # at step 500: between the two checkpoints
    assert np.all(probe.rewards > 0)  # still the entropy reward after the first save
    before = SAC("MlpPolicy", taught.env, **small_sac())
    before.load_replay_buffer(tmp_path / "rl_model_replay_buffer_300_steps.pkl")
    saved = before.replay_buffer
    assert saved.pos == 299  # SB3 saves in `on_step`, before storing the step's transition
    np.testing.assert_array_equal(saved.observations[:299], model.replay_buffer.observations[:299])
    assert np.all(saved.sample(16).rewards.numpy() == 0)  # SB3's own batches: 0 before a session

    after = SAC("MlpPolicy", taught.env, **small_sac())
    after.load_replay_buffer(tmp_path / "rl_model_replay_buffer_600_steps.pkl")
    relabelled = after.replay_buffer.rewards[:599]
    np.testing.assert_array_equal(relabelled, model.replay_buffer.rewards[:599])
    assert np.ptp(relabelled) > 0  # the learned reward of the session at step 500
