"""A run stopped at an episode end and continued from what `save` (and SB3's own
`model.save`, `save_replay_buffer`) wrote asks the same questions and reaches the same
buffer rewards as an uninterrupted one (same machine), with one environment or two; one
saved within an episode is refused when it would train again."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import SAC

from seqrank.sb3 import PreferenceFeedback
from support.sb3_runs import SMALL_SAC, feedback

STEPS, STOP = 1400, 700  # sessions at 500, 900, 1300: one before the stop, two after


def stopped_and_continued(folder, stop, steps=STEPS, **settings):
    """The feedback and SAC of a run stopped at `stop` (saved, deleted, loaded) and
    continued to `steps`."""
    first = feedback(steps=steps, max_feedback=30, **settings)
    model = SAC("MlpPolicy", first.env, seed=4, **SMALL_SAC)
    model.learn(stop, callback=first)
    first.save(folder / "feedback")
    model.save(folder / "agent")
    model.save_replay_buffer(folder / "buffer")
    del model, first

    again = PreferenceFeedback.load(folder / "feedback")
    continued = SAC.load(folder / "agent", env=again.env)
    continued.load_replay_buffer(folder / "buffer")
    continued.learn(steps - stop, callback=again, reset_num_timesteps=False)
    return again, continued


@pytest.mark.parametrize("n_envs", [1, 2])
def test_a_continued_run_equals_an_uninterrupted_one(tmp_path, n_envs):
    whole = feedback(steps=STEPS, max_feedback=30, n_envs=n_envs)
    uninterrupted = SAC("MlpPolicy", whole.env, seed=4, **SMALL_SAC)
    uninterrupted.learn(STEPS, callback=whole)
    # with two environments, 700 steps are 350 of each: 7 episodes of 50
    again, continued = stopped_and_continued(tmp_path, STOP, n_envs=n_envs)

    assert whole.run.counters.sessions == again.run.counters.sessions == 3
    assert again.labels.asked == whole.labels.asked  # the same questions, in order
    assert len(again.labels) == len(whole.labels)
    rows = STEPS // n_envs
    assert continued.replay_buffer.pos == uninterrupted.replay_buffer.pos == rows
    rewards = continued.replay_buffer.rewards[:rows]
    np.testing.assert_array_equal(rewards, uninterrupted.replay_buffer.rewards[:rows])
    for mine, theirs in zip(
        again.run.reward_model.net.parameters(),
        whole.run.reward_model.net.parameters(),
        strict=True,
    ):
        assert torch.equal(mine, theirs)
    assert (tmp_path / "feedback" / "labels.jsonl").read_text().count(
        '"type": "answer"'
    ) == 10  # saved after one


def test_a_run_saved_within_an_episode_is_refused_when_it_would_train_again(tmp_path):
    with pytest.raises(ValueError) as refused:
        stopped_and_continued(tmp_path, STOP + 20)  # 20 steps into the 15th episode
    line = str(refused.value)
    assert line.startswith(
        f"{tmp_path / 'feedback'} was saved within an episode (environment 0 20 steps into "
        "it): a run continues exactly only from a save at an episode end"
    )
    assert "\n" not in line and "teacher='replay:" in line
