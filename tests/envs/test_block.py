"""block:place (supplementary D.1): geometry, success rule, epsilon schedule, DQN, clips."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from seqrank.agents.dqn import DQN, DQNSettings, EpsilonSchedule
from seqrank.buffer import Batch
from seqrank.config import resolve_config
from seqrank.envs import make_env
from seqrank.envs.block import (
    BLOCK_HALF,
    EPISODE_STEPS,
    GOAL,
    START_LOW,
    START_SIZE,
    TABLE_DEPTH,
    TABLE_WIDTH,
    BlockPlaceEnv,
    KinematicDriver,
    direction_of,
    one_hot,
)


def test_geometry_matches_the_paper():
    assert (TABLE_WIDTH, TABLE_DEPTH) == (0.70, 0.60)
    env = make_env("block:place", 0)
    assert isinstance(env, BlockPlaceEnv) and env.discrete
    assert (env.obs_dim, env.act_dim, env.episode_length) == (5, 8, 50)
    starts = []
    for seed in range(300):
        env.reset(seed=seed)
        starts.append(env.position.copy())
    starts = np.array(starts)
    # the start square: 20 x 20 cm in the top-left corner, filled uniformly
    assert np.all(starts >= START_LOW) and np.all(starts <= START_LOW + START_SIZE)
    assert starts[:, 0].max() - starts[:, 0].min() > 0.18
    assert starts[:, 1].min() >= TABLE_DEPTH - 0.2 - 2 * BLOCK_HALF  # top
    assert starts[:, 0].max() <= 0.2 + 2 * BLOCK_HALF  # left
    assert GOAL[0] > TABLE_WIDTH - 0.1 and GOAL[1] < 0.1  # bottom right


@pytest.mark.parametrize("direction", range(8))
def test_each_action_moves_5_cm_in_its_direction(direction):
    driver = KinematicDriver()
    start = np.array([0.35, 0.30])
    driver.place(start)
    moved = driver.push(direction) - start
    angle = direction * math.pi / 4
    assert np.allclose(moved, [0.05 * math.cos(angle), 0.05 * math.sin(angle)])


def test_pushes_stop_at_the_table_edge():
    driver = KinematicDriver()
    driver.place(np.array([0.03, 0.57]))
    assert np.allclose(driver.push(4), [BLOCK_HALF, 0.57])  # left: stops at the edge
    assert np.allclose(driver.push(2), [BLOCK_HALF, TABLE_DEPTH - BLOCK_HALF])  # up
    assert np.allclose(driver.push(3), [BLOCK_HALF, TABLE_DEPTH - BLOCK_HALF])  # up-left corner


def test_success_within_3_cm_then_the_block_stays():
    env = BlockPlaceEnv()
    env.reset(seed=0)
    env.set_state(np.array([GOAL[0] - 0.055, GOAL[1], 0.0, 0.0]))  # 5.5 cm left of the goal
    _, reward, terminated, truncated, info = env.step(one_hot(0))  # 5 cm right: 0.5 cm off
    assert info["success"] and reward == 0.0 and not terminated and not truncated
    _, reward, *_, info = env.step(one_hot(4))
    assert info["success"] and np.allclose(env.position, [GOAL[0] - 0.005, GOAL[1]])
    env.set_state(np.array([GOAL[0] - 0.085, GOAL[1], 0.0, 0.0]))  # 3.5 cm after a push
    _, reward, *_, info = env.step(one_hot(0))
    assert not info["success"] and reward == pytest.approx(-10 * 0.035)


def test_episodes_last_50_steps_and_states_replay():
    env = BlockPlaceEnv()
    env.reset(seed=4)
    states, truncated, steps = [], False, 0
    while not truncated:
        states.append(env.get_state())
        _, _, terminated, truncated, _ = env.step(np.random.default_rng(steps).random(8))
        steps += 1
        assert not terminated
    assert steps == EPISODE_STEPS
    frames = env.render_states(np.array(states[:30]), None, 96, 96)
    assert frames.shape == (30, 96, 96, 3) and frames.dtype == np.uint8
    env.set_state(states[7])
    assert np.array_equal(env.render_frame(96, 96), frames[7])
    assert not np.array_equal(frames[0], frames[29])  # the block moved


def test_bad_actions_are_named():
    with pytest.raises(ValueError, match="8 action scores"):
        direction_of(np.zeros(3))
    with pytest.raises(ValueError, match="direction 9"):
        direction_of(9)


def test_epsilon_schedule_of_d1():
    schedule = EpsilonSchedule()
    assert [schedule.at(s) for s in (0, 999)] == [1.0, 1.0]
    assert schedule.at(1000) == 0.5 and schedule.at(1099) == 0.5
    assert schedule.at(1100) == pytest.approx(0.49)
    assert schedule.at(1200) == pytest.approx(0.5 * 0.98**2)
    assert schedule.at(1000 + 100 * 79) == pytest.approx(0.5 * 0.98**79)  # 0.1015
    assert schedule.at(1000 + 100 * 80) == 0.1 and schedule.at(10**6) == 0.1


def test_dqn_explores_by_the_schedule_and_learns_a_one_step_bandit():
    settings = DQNSettings(
        hidden=32,
        layers=2,
        lr=1e-2,
        discount=0.0,
        tau=1.0,
        target_update_every=1,
        epsilon=EpsilonSchedule(random_steps=0),
    )
    agent = DQN(3, 4, settings, torch.device("cpu"))
    generator = torch.Generator().manual_seed(0)
    obs = torch.zeros(64, 3)
    action = torch.eye(4)[torch.arange(64) % 4]
    reward = (action.argmax(1) == 2).float().unsqueeze(1)  # action 2 pays
    batch = Batch(obs, action, reward, obs, torch.zeros(64, 1))
    for _ in range(300):
        agent.update(batch, generator)
    assert np.argmax(agent.act(np.zeros(3), True, generator)) == 2
    assert agent.epsilon == 0.5
    # epsilon 0.5 decaying to 0.5 * 0.98^3 over 400 picks: greedy, or random and right a
    # quarter of the time. Four runs of 400 picks from a fresh count, each its own generator.
    right = 1 - 0.75 * np.array([agent.settings.epsilon.at(k) for k in range(400)])
    freqs = []
    for k in range(4):
        agent.acted = 0
        explore = torch.Generator().manual_seed(100 + k)
        picks = [np.argmax(agent.act(np.zeros(3), False, explore)) for _ in range(400)]
        freqs.append(np.mean(np.array(picks) == 2))
    assert agent.acted == 400 and agent.epsilon == pytest.approx(0.5 * 0.98**4)
    # expected 0.636, standard error of the mean of four runs 0.012; 20 training seeds x 4 runs
    # measured means 0.622-0.667 (z -1.2 to 2.6), single runs 0.595-0.683: 4 standard errors
    standard_error = np.sqrt(np.sum(right * (1 - right))) / 400 / 2
    assert abs(np.mean(freqs) - right.mean()) < 4 * standard_error, freqs


def test_presets_follow_table_4():
    paper = resolve_config("block:place", "paper", {})
    assert (paper.critic_lr, paper.reward_lr, paper.feedback_frequency) == (1e-6, 1e-6, 200)
    assert (paper.reward_batch, paper.segment_length, paper.seed_steps) == (50, 30, 1000)
    assert paper.steps - paper.seed_steps == 3000
    with pytest.raises(ValueError, match="block:place learns with DQN"):
        resolve_config("block:place", "small", {"backbone": "mrn"})


def test_the_labelling_page_shows_top_down_block_clips(tmp_path):
    import io

    import av

    from support.pages import Page

    page = Page(tmp_path / "labels", "root", 3, task="block:place", segment_length=30)
    try:
        question = page.question()
        reply = page.client.get(question["left"]["clip"])
        assert reply.status_code == 200
        with av.open(io.BytesIO(reply.content)) as container:
            frames = list(container.decode(container.streams.video[0]))
        assert len(frames) == 30
        for choice in ("left", "right", "equal"):
            page.answer(choice)
        page.done.wait(10)
        assert [a.choice for _, a in page.hub.db.answered_questions()] == ["left", "right", "equal"]
    finally:
        page.close()


def block_config(**overrides):
    values = dict(steps=1600, seed_steps=500, feedback_frequency=200, max_feedback=40)
    values.update(reward_batch=10, eval_every=400, eval_episodes=5, checkpoint_every=100)
    values.update(device="cpu", heldout_pairs=50, hidden=32, reward_hidden=32)
    values.update(overrides)
    return resolve_config("block:place", "small", values)


@pytest.mark.parametrize(
    ("scheme", "teacher"),
    [(s, "oracle") for s in ("pairwise", "root", "ranked")]
    + [("sequential", t) for t in ("oracle", "mistake", "noisy", "skip", "myopic", "equal")],
)
def test_every_scheme_and_teacher_trains_on_block_place(tmp_path, scheme, teacher):
    from support.runs import run

    trainer = run(tmp_path / "run", block_config(scheme=scheme, teacher=teacher, steps=1200))
    summary = trainer.run_dir.read_summary()
    assert summary["asked"] == 40 and summary["steps"] == 1200
    if teacher == "skip":  # B-Pref's skip rule on all-negative returns: everything is skipped
        assert len(trainer.labels) == 0
        return
    assert trainer.labels.segments[0].shape == (30, 13)  # 30 steps x (5 obs + 8 one-hot)
    assert set(np.unique(np.stack(trainer.labels.segments)[:, :, 5:])) <= {0.0, 1.0}


def test_a_resumed_block_run_matches_an_uninterrupted_one(tmp_path):
    from support.runs import resume_after_kill, run, without_timing

    config = block_config()
    finished = run(tmp_path / "full", config)
    resumed, _ = resume_after_kill(tmp_path, config, kill_at=1250, checkpoint=1200)
    assert without_timing(resumed.run_dir.read_metrics()) == without_timing(
        finished.run_dir.read_metrics()
    )
    for a, b in zip(resumed.agent.q.parameters(), finished.agent.q.parameters(), strict=True):
        assert torch.equal(a, b)


def test_dqn_from_oracle_preferences_reaches_the_goal_far_more_often_than_random(tmp_path):
    """Small preset, 4 000 steps, seeds 0-2 on one torch thread (about 20 s a seed on 2
    idle cores). Random actions succeed in 0.35% of episodes (7 of 2 000) and return -288 on
    average. One seed is a coin toss (float rounding differs between CPUs and thread counts),
    so the assertions are on means over three seeds; distributions in learning_thresholds.md.
    """
    from support.runs import run

    finals, bests = [], []
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # small networks: one thread is as fast, and never oversubscribed
    try:
        for seed in (0, 1, 2):
            overrides = {"steps": 4000, "max_feedback": 120, "device": "cpu", "seed": seed}
            config = resolve_config("block:place", "small", overrides)
            trainer = run(tmp_path / f"run{seed}", config)
            evals = [r for r in trainer.run_dir.read_metrics() if r["kind"] == "eval"]
            learned = [r for r in evals if r["step"] > config.first_session_step]
            finals.append(evals[-1]["eval_return"])
            bests.append(max(r["eval_return"] for r in learned))
    finally:
        torch.set_num_threads(threads)
    # 15 seeds (0-14), means over all 455 triples: final return min -109.2, median -71.0,
    # max -45.2 (single seeds -124 to -42); best learned return min -68.1, median -57.2
    # (single seeds -71 to -42). Random actions: -288.
    assert np.mean(finals) > -150.0, finals
    assert np.mean(bests) > -100.0, bests
    # Success itself is not asserted: per seed it is bimodal at 4 000 steps (best success 0-100%,
    # 2 of 15 seeds never above 5%), so no threshold over three seeds is both well inside the
    # measured distribution (triples: max best success min 10%, pooled 3 of 180 episodes) and far
    # above random play (0.35%, 0.6 of 180 episodes expected).
