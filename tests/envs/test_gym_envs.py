"""Gymnasium tasks: `gym:ID` and a user's `module.path:factory`, with terminal states."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from seqrank.config import resolve_config
from seqrank.envs import canonical_task, make_env
from seqrank.envs.gym_env import GymEnv
from seqrank.episodes import Episode, EpisodeStore
from support.pages import Page
from support.runs import run

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
CUSTOM = "examples.point_reach:make_env"
MUJOCO_V5 = ("Hopper-v5", "Walker2d-v5", "HalfCheetah-v5", "Ant-v5")


def gym_config(task: str, **overrides):
    values = dict(
        steps=450,
        seed_steps=100,
        unsup_steps=100,
        feedback_frequency=100,
        max_feedback=6,
        reward_batch=2,
        segment_length=20,
        hidden=32,
        batch=32,
        reward_hidden=32,
        reward_epochs=3,
        eval_every=400,
        eval_episodes=1,
        checkpoint_every=400,
        heldout_pairs=10,
        device="cpu",
        seed=1,
    )
    values.update(overrides)
    return resolve_config(task, "small", values)


@pytest.fixture(autouse=True)
def examples_importable(monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES.parent))


def test_task_names_resolve_and_bad_ones_say_what_is_accepted():
    assert canonical_task("gym:Hopper-v5") == ("gym", "Hopper-v5")
    assert canonical_task(CUSTOM) == ("custom", CUSTOM)
    with pytest.raises(ValueError, match=r"unknown Gymnasium environment 'Hoper-v5'.*accepted"):
        canonical_task("gym:Hoper-v5")
    with pytest.raises(ValueError, match=r"cannot import module 'no_such_module'"):
        canonical_task("no_such_module:make")
    with pytest.raises(ValueError, match=r"has no callable 'nope'"):
        canonical_task("examples.point_reach:nope")


@pytest.mark.parametrize("env_id", MUJOCO_V5)
def test_each_mujoco_v5_task_trains_a_few_hundred_steps_with_feedback(tmp_path, env_id):
    # HalfCheetah never falls: its first session waits for its first 1 000-step episode
    steps = 1250 if env_id == "HalfCheetah-v5" else 450
    trainer = run(tmp_path / env_id, gym_config(f"gym:{env_id}", steps=steps))
    assert trainer.counters.step == steps
    assert trainer.counters.asked == 6  # every session found complete episodes to cut
    env = trainer.env
    assert isinstance(env, GymEnv) and env.clip_source == "state"
    assert env.render_frame(64, 48).shape == (48, 64, 3)


def test_actions_are_rescaled_to_the_task_bounds():
    env = make_env(CUSTOM)
    env.reset(seed=0)
    start = env._env.unwrapped._point.copy()
    env.step(np.ones(2, np.float32))  # +1 is the upper bound: +0.1 on each axis
    assert np.allclose(env._env.unwrapped._point - start, np.minimum(0.1, 1.0 - start))


def test_a_terminal_state_stops_bootstrapping_a_time_limit_does_not(tmp_path):
    trainer = run(tmp_path / "hopper", gym_config("gym:Hopper-v5", steps=300, reward="true"))
    replay = trainer.replay
    batch = replay._batch(replay.table[: len(replay)])
    not_done = batch.not_done.flatten()
    # a random Hopper falls within a few dozen steps: many terminals, each stored as such
    episode_ends = sum(1 for e in trainer.episodes.episodes if len(e.reward) < 1000)
    assert (not_done == 0).sum().item() == episode_ends > 3
    target = trainer.agent.critic_target_value(batch, torch.Generator().manual_seed(0))
    assert torch.all(target.flatten()[not_done == 0] == 0)
    assert torch.all(target.flatten()[not_done == 1] != 0)


def test_short_episodes_give_whole_segments_padded_with_their_last_step():
    store = EpisodeStore(4)
    store.add(Episode(np.arange(3.0)[:, None], np.ones((3, 1)), np.array([1.0, 2.0, 3.0])))
    segments = store.sample_segments(2, 5, np.random.default_rng(0))
    assert segments.features.shape == (2, 5, 2)
    assert segments.rewards[0].tolist() == [1.0, 2.0, 3.0, 0.0, 0.0]
    assert segments.features[0, :, 0].tolist() == [0.0, 1.0, 2.0, 2.0, 2.0]


def test_a_custom_factory_trains_and_its_recorded_frames_are_labelled_on_the_page(tmp_path):
    trainer = run(tmp_path / "run", gym_config(CUSTOM))
    assert trainer.counters.asked == 6 and trainer.env.clip_source == "frames"
    page = Page(tmp_path / "labels", "sequential", 3, task=CUSTOM, segment_length=20)
    try:
        assert page.state()["clip_source"] == "frames"  # the page says where clips come from
        for _ in range(3):
            question, reply = page.answer("left")
            assert reply.status_code == 200
            clip = page.client.get(question["left"]["clip"])
            assert clip.status_code == 200 and clip.content[4:8] == b"ftyp"
        page.done.wait(30)
        assert not page.error and page.state()["status"] == "done"
        states = page.hub.db.segments_by_id([1])[1]["states"]
        assert states is not None  # the frames themselves, kept with the labelled segment
    finally:
        page.close()
