"""`--reward-stop-on`: which labels a session's reward training counts for its early stop.
The default counts every label (PEBBLE's rule, as the paper trains); `asked` counts the
asked pairs only, so that easy inferred pairs (root's: the session's best against ordinary
segments) cannot end a fit after one epoch (results/reward-bench/window-open/)."""

from __future__ import annotations

import pytest
import torch

from seqrank.cli import main
from seqrank.reward.model import RewardTrainResult
from seqrank.training.reward_phase import RewardLearning, RewardSettings


class _Labels:
    """Four pairs over five segments: the 2nd and 4th inferred."""

    def __init__(self) -> None:
        self.inferred = [False, True, False, True]

    def __len__(self) -> int:
        return 4

    def asked_mask(self) -> torch.Tensor:
        return torch.tensor([not inferred for inferred in self.inferred])

    def tensors(self, device):
        segments = torch.zeros(5, 3, 2)
        first, second = torch.tensor([0, 0, 1, 2]), torch.tensor([1, 2, 3, 4])
        return segments, first, second, torch.ones(4)


class _Model:
    device = torch.device("cpu")

    def __init__(self) -> None:
        self.given: dict = {}

    def train(self, *args, **kwargs):
        self.given = kwargs
        return RewardTrainResult(1, 0.0, 1.0, {})


@pytest.mark.parametrize(("stop_on", "counted"), [("all", None), ("asked", [1, 0, 1, 0])])
def test_the_stop_rule_counts_the_labels_the_setting_names(stop_on, counted):
    settings = RewardSettings(10, 4, 0.97, 10, 3, False, 1024, stop_on=stop_on)
    model = _Model()
    learning = RewardLearning(model, _Labels(), None, [], settings, torch.Generator())
    learning.train(run_seed=0, session=0, asked=2)
    marks = model.given["stop_pairs"]
    assert (marks is None) if counted is None else marks.int().tolist() == counted


def test_the_setting_reaches_a_run_and_bad_values_are_named(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--reward-stop-on", "asked", "--device", "cpu", "--dry-run"]) == 0
    assert "reward_stop_on = asked" in capsys.readouterr().err
    assert main(["train", "--reward-stop-on", "some", "--dry-run"]) == 2
    assert "unknown --reward-stop-on 'some'; accepted: all, asked" in capsys.readouterr().err
