"""The reward model's training accuracy, against a count made by hand.

With a learning rate of zero the model never moves, so its verdict on every pair is known
before the fit; the accuracy is then the share of hard labels (1 or 0) it agrees with,
equal labels (0.5) counting neither way.
"""

from __future__ import annotations

import pytest
import torch

from seqrank.reward.model import RewardModel


def frozen_model_and_segments():
    torch.manual_seed(0)
    model = RewardModel(members=1, inputs=3, hidden=8, layers=1, lr=0.0, device=torch.device("cpu"))
    segments = torch.randn(12, 4, 3, generator=torch.Generator().manual_seed(1))
    returns = model.member_returns(segments.numpy())[0]
    return model, segments, returns


def fit_once(model, segments, first, second, labels):
    return model.train(
        segments,
        torch.tensor(first, dtype=torch.long),
        torch.tensor(second, dtype=torch.long),
        torch.tensor(labels, dtype=torch.float32),
        max_epochs=1,
        minibatch=4,
        stop_accuracy=2.0,
        generator=torch.Generator().manual_seed(0),
    )


def test_training_accuracy_counts_hard_labels_only():
    model, segments, returns = frozen_model_and_segments()
    pairs = [(2 * i, 2 * i + 1) for i in range(6)]
    agrees = [1.0 if returns[a] > returns[b] else 0.0 for a, b in pairs]
    # three hard labels the model agrees with, one it disagrees with, two equal labels
    # on pairs it does not call equal
    labels = [agrees[0], agrees[1], agrees[2], 1.0 - agrees[3], 0.5, 0.5]
    first, second = zip(*pairs, strict=True)
    result = fit_once(model, segments, first, second, labels)
    assert result.accuracy == pytest.approx(3 / 4)  # 3 of the 4 hard labels, by hand


def test_a_fit_on_equal_labels_alone_has_nothing_to_score():
    model, segments, _ = frozen_model_and_segments()
    result = fit_once(model, segments, [0, 2, 4], [1, 3, 5], [0.5, 0.5, 0.5])
    assert result.accuracy == 1.0  # no hard label: nothing missed (the fit may stop)
