"""Replay buffer, reward model, state-entropy reward and the MRN meta step."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from seqrank.agents.mrn import PairBatch, meta_reward_step, outer_loss
from seqrank.agents.sac import SAC, SACSettings
from seqrank.buffer import Batch, ReplayBuffer
from seqrank.reward.entropy import RunningMeanStd, knn_distance
from seqrank.reward.model import RewardModel
from support.runs import segment_pairs

CPU = torch.device("cpu")


def test_relabelling_covers_every_transition_of_a_wrapped_ring():
    buffer = ReplayBuffer(capacity=10, obs_dim=2, act_dim=1, device=CPU)
    for i in range(23):  # wraps twice; the write index ends at 3
        buffer.add(
            np.full(2, i, np.float32),
            np.zeros(1, np.float32),
            0.0,
            -1.0,
            np.zeros(2, np.float32),
            False,
        )
    assert len(buffer) == 10 and buffer.index == 3
    buffer.relabel(lambda obs, act: obs[:, :1] * 10, chunk=4)
    assert sorted(buffer.reward[:, 0].tolist()) == [10.0 * i for i in range(13, 23)]


def test_replay_state_round_trip():
    buffer = ReplayBuffer(5, 2, 1, CPU)
    for i in range(7):
        buffer.add(np.full(2, i, np.float32), np.ones(1, np.float32), i, i, np.zeros(2), i == 6)
    copy = ReplayBuffer(5, 2, 1, CPU)
    copy.load_state_dict(buffer.state_dict())
    assert torch.equal(copy.obs, buffer.obs) and copy.index == buffer.index
    assert copy.not_done[1, 0] == 0.0  # the terminal flag of step 6 (slot 1)


def test_reward_model_learns_preferences_and_stops_early():
    """Three seeds (initialisation, data, shuffles); distributions in learning_thresholds.md."""
    epochs, accuracies = [], []
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # tiny minibatches: one thread is as fast, and never oversubscribed
    try:
        for seed in (0, 1, 2):
            torch.manual_seed(seed)
            model = RewardModel(3, 3, 32, 2, 3e-3, CPU)
            segments, first, second, labels = segment_pairs(200, seed=100 + seed)
            generator = torch.Generator().manual_seed(1000 + seed)
            result = model.train(segments, first, second, labels, 200, 64, 0.95, generator)
            assert result.accuracy > 0.95 or result.epochs == 200  # the stopping rule
            epochs.append(result.epochs)
            test_segments, tf, ts, tl = segment_pairs(200, seed=200 + seed)
            pred = model.member_returns(test_segments.numpy()).mean(0)
            hits = (pred[tf.numpy()] > pred[ts.numpy()]) == (tl.numpy() > 0.5)
            accuracies.append(hits.mean())
    finally:
        torch.set_num_threads(threads)
    # seeds 0-19: stopped after 4-126 epochs (median 46) of 200; held-out accuracy 0.89-0.955
    # (median 0.905), mean of three 0.893-0.95 over all 1 140 triples; chance is 0.5. (Stopping
    # at 0.97 instead missed in 1 of 20 seeds, and single-seed accuracy went down to 0.835.)
    assert sum(e < 200 for e in epochs) >= 2, epochs
    assert np.mean(accuracies) > 0.85, accuracies


def test_equal_labels_pull_returns_together_on_the_same_loss_path():
    torch.manual_seed(0)
    model = RewardModel(3, 3, 32, 2, 3e-3, CPU)
    segments, first, second, _ = segment_pairs(50)
    gaps_before = (
        (model.segment_returns(segments[first]) - model.segment_returns(segments[second]))
        .abs()
        .mean()
    )
    labels = torch.full((50,), 0.5)
    model.train(segments, first, second, labels, 50, 64, 2.0, torch.Generator().manual_seed(1))
    with torch.no_grad():
        gaps_after = (
            (model.segment_returns(segments[first]) - model.segment_returns(segments[second]))
            .abs()
            .mean()
        )
    assert gaps_after < 0.5 * gaps_before


def test_running_mean_std_merges_batches_exactly():
    stats = RunningMeanStd()
    batches = [torch.randn(n) * 3 + 1 for n in (1, 7, 100, 33)]
    for batch in batches:
        stats.update(batch)
    everything = torch.cat(batches)
    assert stats.count == len(everything)
    assert stats.mean == pytest.approx(float(everything.mean()), abs=1e-5)
    assert stats.std == pytest.approx(float(everything.std(unbiased=False)), abs=1e-5)


def test_knn_distance_matches_brute_force_across_chunks():
    gen = torch.Generator().manual_seed(0)
    stored = torch.randn(300, 4, generator=gen)
    queries = stored[:20]
    brute = torch.cdist(queries, stored).sort(dim=1).values[:, 5:6]  # 5th neighbour, self skipped
    assert torch.allclose(knn_distance(queries, stored, k=5, chunk=64), brute)


def test_mrn_meta_step_changes_the_reward_and_lowers_its_outer_loss():
    torch.manual_seed(0)
    settings = SACSettings(
        hidden=32,
        layers=2,
        actor_lr=1e-3,
        critic_lr=1e-2,
        alpha_lr=1e-4,
        init_temperature=0.1,
        discount=0.99,
        tau=0.005,
        target_update_every=2,
    )
    agent = SAC(3, 2, settings, CPU)
    model = RewardModel(3, 5, 32, 2, 1e-2, CPU)
    batch = Batch(
        torch.randn(64, 3),
        torch.rand(64, 2) * 2 - 1,
        torch.zeros(64, 1),
        torch.randn(64, 3),
        torch.ones(64, 1),
    )
    first_obs, second_obs = torch.randn(32, 3), torch.randn(32, 3)
    labels = (first_obs[:, 0] > second_obs[:, 0]).float()
    labels[:4] = 0.5  # equal labels go through the same soft-target path
    pairs = PairBatch(first_obs, torch.zeros(32, 2), second_obs, torch.zeros(32, 2), labels)
    before_params = [p.detach().clone() for p in model.net.parameters()]
    critic_before = [p.detach().clone() for p in agent.critic.parameters()]

    def loss() -> float:
        return float(
            outer_loss(agent, model, batch, pairs, torch.Generator().manual_seed(9), 0.1).detach()
        )

    start = loss()
    for _ in range(30):
        meta_reward_step(agent, model, batch, pairs, torch.Generator().manual_seed(9), 0.1)
    assert loss() < start
    assert any(
        not torch.equal(a, b) for a, b in zip(before_params, model.net.parameters(), strict=True)
    )
    assert all(
        torch.equal(a, b) for a, b in zip(critic_before, agent.critic.parameters(), strict=True)
    )
    assert all(p.grad is None for p in agent.critic.parameters())


def test_label_store_keeps_provenance_and_gives_recent_pairs_with_their_segments():
    from seqrank.episodes import Segments
    from seqrank.feedback.closure import augment
    from seqrank.feedback.labels import LabelStore
    from seqrank.types import Answer, AnsweredQuestion, Question

    store = LabelStore()
    for session in range(2):
        features = np.arange(4 * 2 * 3, dtype=np.float32).reshape(4, 2, 3) + 100 * session
        segments = Segments(features, np.ones((4, 2)), [None] * 4, [session] * 4)
        answers = [
            AnsweredQuestion(Question(0, 0, 1, True), Answer.FIRST),
            AnsweredQuestion(Question(1, 1, 2, True), Answer.FIRST),
        ]
        store.add_session(segments, np.ones(4), (0, 1, 2), augment(answers), session)
    assert len(store.segments) == 6 and len(store) == 6  # 2 asked + 1 inferred per session
    assert store.segment_contexts == [0, 0, 0, 1, 1, 1]
    segments, first, second, labels = store.tensors(CPU, last=3)
    assert torch.equal(segments[second[0]], torch.as_tensor(store.segments[store.second[-3]]))
    assert segments.shape == (3, 2, 3)  # only the second session's segments
    assert torch.equal(segments[first[0]], torch.as_tensor(store.segments[store.first[-3]]))
    assert labels.tolist() == store.labels[-3:]
    all_segments, all_first, _, _ = store.tensors(CPU)
    assert all_segments.shape[0] == 6 and len(all_first) == 6
