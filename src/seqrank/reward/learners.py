"""The reward learners by name (`RewardLearner`): plain Bradley-Terry, SURF and RIME.

A new learner is a `reward.model.Learner` registered here; the fit, the run and the
reward benchmark do not change.
"""

from __future__ import annotations

import numpy as np
import torch

from seqrank.choices import RewardLearner
from seqrank.episodes import EpisodeStore
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


def give_unlabelled(learner: Learner, episodes: EpisodeStore, length: int, seed: list[int]) -> None:
    """The unlabelled segment pairs a learner wants before a fit (SURF's), cut uniformly
    from the kept episodes by their own stream: a resumed run cuts the same ones."""
    if learner.unlabelled_pairs and len(episodes):
        rng = np.random.default_rng(seed)
        cut = episodes.sample_segments(2 * learner.unlabelled_pairs, length, rng)
        learner.use_unlabelled(cut.features, cut.rewards.sum(1))
