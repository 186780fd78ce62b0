from __future__ import annotations

import numpy as np
import pytest

from seqrank.envs import PAPER_TASKS, canonical_task, make_env


@pytest.mark.parametrize("task", PAPER_TASKS)
def test_every_paper_task_loads_steps_and_renders(task):
    env = make_env(task, seed=0)
    try:
        obs, info = env.reset(seed=1)
        assert obs.dtype == np.float32 and obs.shape == (env.obs_dim,)
        assert "success" in info
        states, frames = [], []
        for _ in range(5):
            states.append(env.get_state())
            frames.append(env.render_frame(48, 48))
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            assert obs.dtype == np.float32 and np.isfinite(obs).all()
            assert isinstance(reward, float) and "success" in info
            assert not terminated and not truncated
        assert frames[0].shape == (48, 48, 3) and frames[0].dtype == np.uint8
        assert frames[0].std() > 0  # not a blank image
        rerendered = env.render_states(np.stack(states), info.get("task_index"), 48, 48)
        assert np.array_equal(rerendered, np.stack(frames))
    finally:
        env.close()


def test_reset_with_the_same_seed_repeats_the_episode():
    env = make_env("walker_walk")
    actions = np.random.default_rng(0).uniform(-1, 1, (20, env.act_dim))
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=7)
        trajectory = [obs]
        for action in actions:
            trajectory.append(env.step(action)[0])
        runs.append(np.stack(trajectory))
    other, _ = env.reset(seed=8)
    assert np.array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0][0], other)
    env.close()


def test_dmc_episode_ends_by_time_limit_and_actions_are_clipped():
    env = make_env("dmc:cartpole_balance")
    env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated:
        _, _, terminated, truncated, _ = env.step(np.full(env.act_dim, 5.0))  # clipped to 1
        steps += 1
        assert not terminated
    assert steps == env.episode_length == 1000
    env.close()


def test_metaworld_task_index_is_drawn_from_the_seed():
    env = make_env("metaworld:reach-v3")
    seen = {env.reset(seed=s)[1]["task_index"] for s in range(12)}
    assert len(seen) > 1 and all(0 <= i < 50 for i in seen)
    assert env.reset(seed=3)[1]["task_index"] == env.reset(seed=3)[1]["task_index"]
    assert env.episode_length == 500
    env.close()


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("walker_walk", ("dmc", "walker_walk")),
        ("dmc:ball_in_cup_catch", ("dmc", "ball_in_cup_catch")),
        ("door-open", ("metaworld", "door-open-v3")),
        ("metaworld:hammer-v3", ("metaworld", "hammer-v3")),
    ],
)
def test_task_names(name, expected):
    assert canonical_task(name) == expected


def test_unknown_task_lists_what_is_accepted():
    with pytest.raises(ValueError, match="unknown task 'walker'; accepted: walker_walk"):
        canonical_task("walker")


def test_fast_rendering_for_clips_is_repeatable():
    env = make_env("dmc:cartpole_swingup", 0)
    env.reset(seed=0)
    state = env.get_state()
    full = env.render_frame(64, 64)
    env.use_fast_rendering()
    env.set_state(state)
    fast = env.render_frame(64, 64)
    env.set_state(state)
    assert np.array_equal(fast, env.render_frame(64, 64))
    assert fast.shape == full.shape and not np.array_equal(fast, full)  # no shadows now
    env.close()
