"""A run stopped at an episode end and continued from what `save` (and SB3's own
`model.save`, `save_replay_buffer`) wrote asks the same questions and reaches the same
buffer rewards as an uninterrupted one (same machine)."""

from __future__ import annotations

import numpy as np
import torch
from stable_baselines3 import SAC

from seqrank.sb3 import PreferenceFeedback
from support.sb3_runs import SMALL_SAC, feedback

STEPS, STOP = 1400, 700  # sessions at 500, 900, 1300: one before the stop, two after


def test_a_continued_run_equals_an_uninterrupted_one(tmp_path):
    whole = feedback(steps=STEPS, max_feedback=30)
    uninterrupted = SAC("MlpPolicy", whole.env, seed=4, **SMALL_SAC)
    uninterrupted.learn(STEPS, callback=whole)

    first = feedback(steps=STEPS, max_feedback=30)
    model = SAC("MlpPolicy", first.env, seed=4, **SMALL_SAC)
    model.learn(STOP, callback=first)
    first.save(tmp_path / "feedback")
    model.save(tmp_path / "agent")
    model.save_replay_buffer(tmp_path / "buffer")
    del model, first

    again = PreferenceFeedback.load(tmp_path / "feedback")
    continued = SAC.load(tmp_path / "agent", env=again.env)
    continued.load_replay_buffer(tmp_path / "buffer")
    continued.learn(STEPS - STOP, callback=again, reset_num_timesteps=False)

    assert whole.run.counters.sessions == again.run.counters.sessions == 3
    assert again.labels.asked == whole.labels.asked  # the same questions, in order
    assert len(again.labels) == len(whole.labels)
    rewards = continued.replay_buffer.rewards[:STEPS]
    np.testing.assert_array_equal(rewards, uninterrupted.replay_buffer.rewards[:STEPS])
    for mine, theirs in zip(
        again.run.reward_model.net.parameters(),
        whole.run.reward_model.net.parameters(),
        strict=True,
    ):
        assert torch.equal(mine, theirs)
    assert (tmp_path / "feedback" / "labels.jsonl").read_text().count(
        '"type": "answer"'
    ) == 10  # saved after one
