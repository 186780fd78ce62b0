"""The reward learners by name (`RewardLearner`): plain Bradley-Terry, SURF and RIME.

A new learner is a `reward.model.Learner` registered here; the fit, the run and the
reward benchmark do not change.
"""

from __future__ import annotations

import torch

from seqrank.choices import RewardLearner
from seqrank.reward.model import Learner, PlainLearner
from seqrank.reward.rime import RimeLearner, RimeSettings
from seqrank.reward.surf import SurfLearner, SurfSettings


def make_learner(
    name: RewardLearner | str,
    questions: int,
    generator: torch.Generator,
    surf: SurfSettings | None = None,
    rime: RimeSettings | None = None,
) -> Learner:
    """The learner `name`; `questions` asked per session sizes SURF's unlabelled pairs,
    `generator` (the run's) draws its crops and unlabelled batches."""
    kind = RewardLearner(name)
    if kind is RewardLearner.SURF:
        return SurfLearner(surf or SurfSettings(), questions, generator)
    if kind is RewardLearner.RIME:
        return RimeLearner(rime or RimeSettings())
    return PlainLearner()
