"""Labels over a dataset's segments: the schemes' sessions and closure as a run asks them,
the label file, the budget a dataset can give, and the reward fit and relabelling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import spearmanr

from seqrank.feedback.label_file import read_label_file
from seqrank.offline.dataset import OfflineDataset
from seqrank.offline.labelling import (
    distinct_segments,
    fit_reward,
    label_dataset,
    relabel,
    save_labels,
)

SCHEMES = ("pairwise", "sequential", "root", "ranked")


def synthetic(episodes: int = 6, steps: int = 100, seed: int = 0) -> OfflineDataset:
    """Episodes of cartpole's sizes (5 + 1) whose true reward is the first observation."""
    rng = np.random.default_rng(seed)
    rows = episodes * steps
    obs = rng.normal(size=(rows + 1, 5)).astype(np.float32)
    ends = np.zeros(rows, bool)
    ends[steps - 1 :: steps] = True
    return OfflineDataset(
        "dmc:cartpole_swingup",
        obs[:-1],
        rng.uniform(-1, 1, (rows, 1)).astype(np.float32),
        obs[:-1, 0].copy(),
        obs[1:],
        np.zeros(rows, bool),
        ends,
        np.arange(0, rows, steps),
        {"dataset_id": "synthetic-v0"},
    )


def true_returns(labels) -> np.ndarray:
    return np.asarray(labels.segment_returns)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_each_scheme_asks_its_budget_about_the_datasets_segments(scheme):
    """20 questions in sessions of 8, 8 and 4; the oracle's labels and every pair the
    closure infers agree with the segments' true returns; the ranking schemes infer pairs,
    pairwise none; every segment is a window of the dataset's rows."""
    dataset = synthetic()
    labels = label_dataset(dataset, scheme, "oracle", 20, 8, 10, seed=1)
    assert len(labels.asked) == 20
    assert [s for s, *_ in labels.asked].count(2) == 4  # the last session asks the rest
    inferred = sum(labels.inferred)
    assert inferred == len(labels) - 20
    assert inferred == 0 if scheme == "pairwise" else inferred > 0
    returns = true_returns(labels)
    for first, second, label in zip(labels.first, labels.second, labels.labels, strict=True):
        assert label == (1.0 if returns[first] > returns[second] else 0.0)
    rows = np.concatenate([dataset.observations, dataset.actions], 1)
    for segment in labels.segments[:5]:
        starts = np.flatnonzero((rows[:, :] == segment[0]).all(1))
        assert any(np.array_equal(rows[s : s + 10], segment) for s in starts)


def test_the_same_seed_asks_the_same_questions():
    dataset = synthetic()
    first = label_dataset(dataset, "root", "oracle", 12, 6, 10, seed=3)
    again = label_dataset(dataset, "root", "oracle", 12, 6, 10, seed=3)
    other = label_dataset(dataset, "root", "oracle", 12, 6, 10, seed=4)
    assert np.array_equal(np.stack(first.segments), np.stack(again.segments))
    assert not np.array_equal(np.stack(first.segments)[:4], np.stack(other.segments)[:4])


def test_the_labels_round_trip_through_the_label_file(tmp_path):
    """The file holds every question in order with its segments; replayed as a teacher
    over the same dataset, it gives back the same labelled pairs."""
    dataset = synthetic()
    labels = label_dataset(dataset, "sequential", "oracle", 15, 5, 10, seed=2)
    path = tmp_path / "labels.jsonl"
    assert save_labels(labels, dataset, path, "sequential", "oracle", 10) == 15
    read = read_label_file(path)
    assert read.header["task"] == "dmc:cartpole_swingup" and read.header["segment_length"] == 10
    assert read.header["dataset"] == "synthetic-v0"
    assert [a["answer"] for a in read.answers] == [answer for *_, answer, _ in labels.asked]
    for answer, (_, _, first, _, _, _) in zip(read.answers, labels.asked, strict=True):
        features = np.asarray(read.segments[answer["first"]]["features"], np.float32)
        np.testing.assert_array_equal(features, labels.segments[first])
    replayed = label_dataset(dataset, "sequential", f"replay:{path}", 15, 5, 10, seed=9)
    assert replayed.labels == labels.labels and replayed.inferred == labels.inferred
    pairs = [
        (labels.segments[f], labels.segments[s])
        for f, s in zip(labels.first, labels.second, strict=True)
    ]
    again = [(replayed.segments[f], replayed.segments[s])
             for f, s in zip(replayed.first, replayed.second, strict=True)]  # fmt: skip
    assert all(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
               for a, b in zip(pairs, again, strict=True))  # fmt: skip


def test_a_crowd_labels_a_dataset_with_each_pair_annotated():
    labels = label_dataset(synthetic(), "root", "crowd:oracle+oracle", 12, 6, 10, seed=0)
    assert len(labels.asked) >= 12 and set(labels.annotator) == {"oracle", "oracle-2"}


def test_a_budget_beyond_the_datasets_distinct_segments_is_refused():
    """Two episodes of 20 steps hold 2 x (20 - 10 + 1) = 22 segments of 10 steps: 11
    pairwise questions (22 segments) fit, 12 do not; root's 21 questions in one session
    need 22."""
    dataset = synthetic(episodes=2, steps=20)
    assert distinct_segments(dataset, 10) == 22
    assert len(label_dataset(dataset, "pairwise", "oracle", 11, 11, 10).asked) == 11
    with pytest.raises(ValueError, match="needs 24 segments of 10 steps; dataset synthetic-v0 "
                       "holds 22 distinct ones"):  # fmt: skip
        label_dataset(dataset, "pairwise", "oracle", 12, 12, 10)
    assert len(label_dataset(dataset, "root", "oracle", 21, 21, 10).asked) == 21
    with pytest.raises(ValueError, match="needs 23 segments"):
        label_dataset(dataset, "root", "oracle", 22, 22, 10)


def test_a_segment_is_no_longer_than_an_episode_unless_past_a_terminal_state():
    """Segments are padded as an absorbing terminal state would show: an episode cut by a
    time limit bounds the segment length; episodes that end in a terminal state may be
    shorter (padded), as long as one is as long as a segment."""
    from dataclasses import replace

    from seqrank.offline.labelling import segment_limit

    dataset = synthetic(episodes=3, steps=20)
    assert segment_limit(dataset) == (20, True)
    assert len(label_dataset(dataset, "pairwise", "oracle", 1, 1, 20).asked) == 1
    with pytest.raises(ValueError, match="segment_length 21 is longer than the shortest "
                       "episode of dataset synthetic-v0 that ends without a terminal state "
                       r"\(20 steps; .*\); accepted: 1 to 20$"):  # fmt: skip
        label_dataset(dataset, "pairwise", "oracle", 1, 1, 21)
    terminal = np.zeros(len(dataset), bool)
    terminal[[9, 59]] = True  # episodes of 10, 40 and 10 steps, the first and last terminal
    uneven = replace(dataset, terminations=terminal, starts=np.array([0, 10, 50]))
    assert segment_limit(uneven) == (40, True)
    assert len(label_dataset(uneven, "pairwise", "oracle", 1, 1, 40).asked) == 1
    uneven = replace(uneven, terminations=terminal | (np.arange(60) == 49))
    assert segment_limit(uneven) == (40, False)  # every episode terminal: the longest
    with pytest.raises(ValueError, match=r"every episode of dataset synthetic-v0 \(the "
                       r"longest has 40 steps\); accepted: 1 to 40"):  # fmt: skip
        label_dataset(uneven, "pairwise", "oracle", 1, 1, 41)


@pytest.mark.parametrize(
    ("scheme", "teacher", "message"),
    [
        ("bubble", "oracle", "unknown scheme 'bubble'; accepted: pairwise, sequential"),
        ("root", "human", "'human' answers on the labelling page"),
        ("root", "sage", "unknown teacher"),
    ],
)
def test_bad_schemes_and_teachers_are_named(scheme, teacher, message):
    with pytest.raises(ValueError, match=message):
        label_dataset(synthetic(), scheme, teacher, 5)


def test_the_fitted_reward_relabels_the_dataset_in_the_true_rewards_order():
    """200 root questions of the oracle: the learned per-step reward ranks the dataset's
    transitions as the true one does (Spearman above 0.9; it is a linear reward); every
    other column is left as it was."""
    dataset = synthetic()
    labels = label_dataset(dataset, "root", "oracle", 200, 25, 10, seed=0)
    relabelled = relabel(dataset, fit_reward(dataset, labels, seed=0))
    assert spearmanr(relabelled.rewards, dataset.rewards).statistic > 0.9
    assert relabelled.rewards.dtype == np.float32 and relabelled.meta["rewards"] == "learned"
    np.testing.assert_array_equal(relabelled.observations, dataset.observations)
    np.testing.assert_array_equal(relabelled.starts, dataset.starts)
    assert dataset.meta.get("rewards") is None  # the dataset itself is unchanged
