"""What `PreferenceFeedback` promises an SB3 agent, checked against values computed by
hand: the relabelled buffer is the ensemble's mean, the true reward never reaches the
agent, pre-training batches carry the state-entropy reward, the critic is reset once."""

from __future__ import annotations

import copy
import csv

import numpy as np
import pytest
import torch
from stable_baselines3 import A2C, DQN, PPO, SAC, TD3
from stable_baselines3.common.logger import configure

from seqrank.errors import SettingError
from seqrank.sb3 import PreferenceReplayBuffer, agents
from support.sb3_envs import SENTINEL
from support.sb3_runs import SMALL_SAC, feedback


def ensemble_mean_by_hand(model, features: np.ndarray) -> np.ndarray:
    """The members' MLPs in numpy (LeakyReLU 0.01 hidden layers, tanh output), averaged."""
    weights = [w.detach().numpy() for w in model.net.weights]
    biases = [b.detach().numpy() for b in model.net.biases]
    outputs = []
    for m in range(len(weights[0])):
        x = features.astype(np.float64)
        for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
            x = x @ w[m] + b[m]
            x = np.tanh(x) if i == len(weights) - 1 else np.where(x > 0, x, 0.01 * x)
        outputs.append(x[:, 0])
    return np.mean(outputs, axis=0)


@pytest.mark.parametrize("agent", [SAC, TD3])
def test_after_the_sessions_every_buffer_reward_is_the_models_prediction(agent):
    fb = feedback(steps=1400, max_feedback=30)
    # a copy: SAC writes `use_sde` into the policy_kwargs it is given, which TD3 refuses
    model = agent("MlpPolicy", fb.env, seed=1, **copy.deepcopy(SMALL_SAC))
    model.learn(1400, callback=fb)
    assert fb.run.counters.sessions == 3
    assert fb.state.pretraining and fb.state.critic_reset  # PEBBLE's pieces: on for SAC and TD3
    buffer = model.replay_buffer
    features = np.concatenate([buffer.observations[:1400, 0], buffer.actions[:1400, 0]], 1)
    expected = ensemble_mean_by_hand(fb.run.reward_model, features)
    np.testing.assert_allclose(buffer.rewards[:1400, 0], expected, atol=1e-5)
    assert np.ptp(expected) > 0.01  # a fitted model, not a constant
    np.testing.assert_allclose(fb.reward(features[:, :2], features[:, 2:]), expected, atol=1e-5)


def test_a_discrete_agent_relabels_with_one_hot_actions():
    fb = feedback("block:place", steps=900, seed_steps=300, unsup_steps=0, max_feedback=20)
    model = DQN("MlpPolicy", fb.env, seed=0, learning_starts=100, batch_size=32)
    model.learn(900, callback=fb)
    assert fb.run.counters.sessions == 2 and not fb.state.pretraining and not fb.state.critic_reset
    buffer = model.replay_buffer
    one_hot = np.eye(8)[buffer.actions[:900, 0, 0].astype(int)]
    features = np.concatenate([buffer.observations[:900, 0], one_hot], 1)
    expected = ensemble_mean_by_hand(fb.run.reward_model, features)
    np.testing.assert_allclose(buffer.rewards[:900, 0], expected, atol=1e-5)


@pytest.mark.parametrize("agent", [SAC, PPO, A2C])
def test_the_agent_never_sees_the_true_reward(agent):
    """Mutation: the task's true reward is a huge constant; the teacher sees it (it is in
    the episodes), the agent's buffer never holds it (learned rewards are tanh-bounded)."""
    fb = feedback("support.sb3_envs:make_sentinel", steps=1400, max_feedback=30)
    options = {SAC: SMALL_SAC, PPO: dict(n_steps=100, batch_size=50), A2C: dict(n_steps=20)}[agent]
    model = agent("MlpPolicy", fb.env, seed=0, **options)
    seen: list[np.ndarray] = []
    if agent is SAC:  # every batch SAC trains on, pre-training included
        sample = model.replay_buffer.sample
        model.replay_buffer.sample = lambda *a, **k: _keep(seen, sample(*a, **k))
    model.learn(600, callback=fb)
    assert all(e.reward.min() == SENTINEL for e in fb.run.episodes.episodes)
    if agent is SAC:  # learned rewards are tanh-bounded
        assert np.abs(model.replay_buffer.rewards).max() <= 1.0
    else:  # on-policy rewards carry a bootstrapped value where an episode was cut short
        assert np.abs(model.rollout_buffer.rewards).max() < 1e3
    assert all(np.abs(rewards).max() < 1e3 for rewards in seen)


def _keep(seen, batch):
    seen.append(batch.rewards.numpy())
    return batch


def test_pretraining_batches_carry_the_state_entropy_reward_worked_out_by_hand():
    fb = feedback()
    model = SAC("MlpPolicy", fb.env, seed=0, **SMALL_SAC)
    model.learn(60, callback=fb)  # stored transitions, no update yet (learning_starts 100)
    assert isinstance(model.replay_buffer, PreferenceReplayBuffer)
    assert model.replay_buffer.entropy is not None  # pre-training: no session yet
    torch.manual_seed(0)
    batch = model.replay_buffer.sample(16)
    stored = model.replay_buffer.observations[:60, 0].astype(np.float64)
    queries = batch.observations.numpy().astype(np.float64)
    distances = np.linalg.norm(queries[:, None] - stored[None], axis=-1)
    kth = np.sort(distances, axis=1)[:, fb.config.knn_k]  # the query itself is at 0
    np.testing.assert_allclose(batch.rewards.numpy()[:, 0], kth / kth.std(), rtol=1e-4)


def test_pretraining_without_the_preference_replay_buffer_is_refused_in_one_line():
    fb = feedback()
    model = SAC("MlpPolicy", fb.env, seed=0, policy_kwargs=dict(net_arch=[32, 32]))
    expected = r"^pretrain: SAC pre-trains .* replay_buffer_class=PreferenceReplayBuffer\) "
    with pytest.raises(
        SettingError, match=expected + r"\(from seqrank.sb3\), or pass pretrain=False$"
    ):
        model.learn(10, callback=fb)
    plain = feedback(pretrain=False)  # SB3's own buffer serves an agent that does not pre-train
    agent = SAC("MlpPolicy", plain.env, seed=0, policy_kwargs=dict(net_arch=[32, 32]))
    agent.learn(10, callback=plain)


def test_reset_critic_gives_fresh_critic_weights_its_target_a_copy_and_keeps_the_actor():
    fb = feedback()
    model = SAC("MlpPolicy", fb.env, seed=0, **SMALL_SAC)
    model.learn(200, callback=fb)  # some updates: the optimiser has moments
    critic_before = [p.detach().clone() for p in model.critic.parameters()]
    actor_before = [p.detach().clone() for p in model.actor.parameters()]
    agents.reset_critic(model, updates=0)
    for before, now in zip(critic_before, model.critic.parameters(), strict=True):
        assert not torch.equal(before, now)
    pairs = zip(model.critic.parameters(), model.critic_target.parameters(), strict=True)
    for critic, target in pairs:
        assert torch.equal(critic, target)
    for before, now in zip(actor_before, model.actor.parameters(), strict=True):
        assert torch.equal(before, now)
    assert not model.critic.optimizer.state


def test_pebbles_pieces_are_on_for_sac_only_at_the_first_session(monkeypatch, tmp_path):
    resets = []
    monkeypatch.setattr(agents, "reset_critic", lambda model, updates: resets.append(updates))
    fb = feedback(steps=1400, max_feedback=30, updates_after_reset=7)
    model = SAC("MlpPolicy", fb.env, seed=0, **SMALL_SAC)
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(1400, callback=fb)
    assert fb.state.pretraining and fb.state.critic_reset and resets == [7]
    with open(tmp_path / "progress.csv") as rows:
        logged = [row for row in csv.DictReader(rows) if row.get("feedback/pairs_per_question")]
    assert len(logged) == 3  # a row per session, under seqrank's names
    assert float(logged[-1]["feedback/total_asked"]) == 30
    assert 0 <= float(logged[-1]["reward/heldout_accuracy"]) <= 1

    ppo_feedback = feedback(steps=1400, max_feedback=30)
    ppo = PPO("MlpPolicy", ppo_feedback.env, seed=0, n_steps=100, batch_size=50)
    ppo.learn(300, callback=ppo_feedback)
    assert not ppo_feedback.state.pretraining and not ppo_feedback.state.critic_reset
    assert ppo_feedback.config.first_session_step == 100  # no pre-training phase
    assert ppo_feedback.run.counters.sessions == 1 and resets == [7]
