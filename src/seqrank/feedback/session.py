"""One feedback session of a training run: cut segments, ask, augment, store the labels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from seqrank.buffer import EpisodeStore
from seqrank.config import TrainConfig
from seqrank.feedback.closure import AugmentationStats, augment
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.schemes import get_scheme, segments_needed
from seqrank.feedback.selection import make_chooser
from seqrank.feedback.teachers import ScriptedTeacher
from seqrank.reward_model import RewardModel
from seqrank.types import Answer


@dataclass(frozen=True)
class SessionOutcome:
    stats: AugmentationStats
    segments_used: int


def run_session(
    config: TrainConfig,
    questions: int,
    episodes: EpisodeStore,
    reward_model: RewardModel,
    teacher: ScriptedTeacher,
    labels: LabelStore,
    session: int,
    rng: np.random.Generator,
    informative: bool,
) -> SessionOutcome:
    """Ask `questions` with the configured scheme; store asked and inferred pairs.

    With an informative selection (after the first session) the candidate pool is
    `oversample` times what the scheme needs, and the chooser picks among it.
    """
    needed = segments_needed(config.scheme, questions)
    use_model = informative and config.selection != "uniform"
    pool = needed * (config.oversample if use_model else 1)
    segments = episodes.sample_segments(pool, config.segment_length, rng)
    features, rewards = segments.features, segments.rewards
    true_returns = rewards.sum(axis=1)
    member_returns = reward_model.member_returns(features) if use_model else None
    chooser = make_chooser(config.selection if use_model else "uniform", member_returns)

    def ask(first: int, second: int) -> Answer:
        return teacher.answer(rewards[first], rewards[second], rng)

    record = get_scheme(config.scheme)(pool, questions, ask, rng, chooser)
    augmentation = augment(record.answers, true_returns.tolist())
    labels.add_session(segments, true_returns, record.segments, augmentation, session)
    return SessionOutcome(augmentation.stats, len(record.segments))
