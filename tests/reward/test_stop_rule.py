"""The stop rule counted over some pairs only (`stop_pairs`: the asked ones, issue 46 item
2), against counts made by hand on a model that never moves (learning rate zero)."""

from __future__ import annotations

import pytest
import torch

from seqrank.reward.model import PlainLearner, RewardModel


def frozen():
    torch.manual_seed(0)
    model = RewardModel(members=1, inputs=3, hidden=8, layers=1, lr=0.0, device=torch.device("cpu"))
    segments = torch.randn(12, 4, 3, generator=torch.Generator().manual_seed(1))
    returns = model.member_returns(segments.numpy())[0]
    pairs = [(2 * i, 2 * i + 1) for i in range(6)]
    agrees = [1.0 if returns[a] > returns[b] else 0.0 for a, b in pairs]
    # hard labels the model agrees with (0, 1, 2), one it disagrees with (3), and two
    # more it agrees with (4, 5)
    labels = [agrees[0], agrees[1], agrees[2], 1.0 - agrees[3], agrees[4], agrees[5]]
    return model, segments, pairs, labels


def fit(model, segments, pairs, labels, counted=None, epochs=1, learner=None):
    first, second = zip(*pairs, strict=True)
    return model.train(
        segments,
        torch.tensor(first, dtype=torch.long),
        torch.tensor(second, dtype=torch.long),
        torch.tensor(labels, dtype=torch.float32),
        max_epochs=epochs,
        minibatch=4,
        stop_accuracy=0.9,
        generator=torch.Generator().manual_seed(0),
        stop_pairs=None if counted is None else torch.tensor(counted),
        learner=learner,
    )


def test_the_stop_rule_counts_only_the_pairs_it_is_given():
    model, segments, pairs, labels = frozen()
    # every pair: 5 of 6 right, 0.833, never above 0.9: all 3 epochs run
    every = fit(model, segments, pairs, labels, epochs=3)
    assert (every.accuracy, every.epochs) == (pytest.approx(5 / 6), 3)
    # without the pair it gets wrong: 5 of 5, above 0.9 after the first epoch
    counted = [True, True, True, False, True, True]
    asked = fit(model, segments, pairs, labels, counted, epochs=3)
    assert (asked.accuracy, asked.epochs) == (1.0, 1)
    # the wrong pair and two right ones: 2 of 3
    counted = [False, True, True, True, False, False]
    assert fit(model, segments, pairs, labels, counted).accuracy == pytest.approx(2 / 3)
    # nothing counted: nothing missed (the fit may stop), as for equal labels alone
    assert fit(model, segments, pairs, labels, [False] * 6).accuracy == 1.0


class _LastFourBackwards(PlainLearner):
    """Chooses the epoch's pairs as RIME does, a subset, here also reordered."""

    def epoch_pairs(self, model, segments, pairs):
        first, second, labels = pairs
        return first[2:].flip(0), second[2:].flip(0), labels[2:].flip(0)


def test_the_counted_pairs_follow_a_learner_that_chooses_and_reorders_them():
    """A pair is counted by its two segments, whatever place the learner gives it: pairs
    2 to 5 are trained on, of which 3 (wrong) and 4 (right) are counted: 1 of 2."""
    model, segments, pairs, labels = frozen()
    counted = [True, True, False, True, True, False]
    result = fit(model, segments, pairs, labels, counted, learner=_LastFourBackwards())
    assert result.accuracy == pytest.approx(1 / 2)
