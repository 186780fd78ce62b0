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

# Unlabelled pairs cut for one fit at most: SURF's walker command reaches 100 per question
# x 100 questions; a Meta-World run of 10 000 questions would otherwise cut 100 000 pairs
# (1.7 GB) before every fit.
MAX_UNLABELLED = 10_000


def make_learner(
    name: RewardLearner | str,
    generator: torch.Generator,
    surf: SurfSettings | None = None,
    rime: RimeSettings | None = None,
) -> Learner:
    """The learner `name`; `generator` (its own stream) draws SURF's crops and unlabelled
    batches."""
    kind = RewardLearner(name)
    if kind is RewardLearner.SURF:
        return SurfLearner(surf or SurfSettings(), generator)
    if kind is RewardLearner.RIME:
        return RimeLearner(rime or RimeSettings())
    return PlainLearner()


def give_unlabelled(
    learner: Learner, episodes: EpisodeStore, length: int, asked: int, seed: list[int]
) -> None:
    """The unlabelled segment pairs a learner wants before a fit (SURF's: so many per
    question `asked` so far, at most `MAX_UNLABELLED`), cut uniformly from the kept episodes
    by their own stream: a resumed run cuts the same ones."""
    pairs = min(learner.unlabelled_per_question * asked, MAX_UNLABELLED)
    if pairs and len(episodes):
        rng = np.random.default_rng(seed)
        cut = episodes.sample_segments(2 * pairs, length, rng)
        learner.use_unlabelled(cut.features, cut.rewards.sum(1))
