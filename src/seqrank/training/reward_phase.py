"""Reward learning during a run: fit the ensemble to every label so far, relabel the
replay buffer with the new reward, and measure the reward on held-out segments."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from seqrank.buffer import RewardFn, RewardTable
from seqrank.episodes import EpisodeStore
from seqrank.feedback.labels import LabelStore
from seqrank.reward.learners import give_unlabelled
from seqrank.reward.model import Learner, PlainLearner, RewardModel, RewardTrainResult
from seqrank.training.evaluation import reward_quality


@dataclass(frozen=True)
class RewardSettings:
    epochs: int
    minibatch: int
    stop_accuracy: float
    heldout_pairs: int
    segment_length: int
    sync_every_step: bool  # read the loss back per minibatch (reference) or per epoch (fast)
    relabel_chunk: int
    stop_on: str = "all"  # the labels the early stop counts: all, or the asked ones


class RewardLearning:
    def __init__(
        self,
        reward_model: RewardModel,
        labels: LabelStore,
        replay: RewardTable,
        episodes: EpisodeStore,
        settings: RewardSettings,
        generator: torch.Generator,
        learner: Learner | None = None,
    ):
        self.model, self.labels, self.replay = reward_model, labels, replay
        self.episodes, self.settings, self.generator = episodes, settings, generator
        self.learner = learner if learner is not None else PlainLearner()  # checkpointed

    def reward_fn(self, trained: bool) -> RewardFn | None:
        """The learned reward for new transitions; none before the first session."""
        return self.model.reward if trained else None

    def train(self, run_seed: int, session: int, asked: int) -> RewardTrainResult | None:
        """Fit every label so far (`asked`: the questions asked so far). Every answer may be
        a skip (B-Pref's skip teacher on all-negative returns): then there is nothing to
        fit, and the model stays."""
        if not len(self.labels):
            return None
        s = self.settings
        give_unlabelled(
            self.learner, self.episodes, s.segment_length, asked, [run_seed, 3, session]
        )
        segments, first, second, labels = self.labels.tensors(self.model.device)
        counted = None  # the pairs the early stop counts: every pair, or the asked ones
        if s.stop_on == "asked":
            counted = self.labels.asked_mask()
        return self.model.train(
            segments,
            first,
            second,
            labels,
            s.epochs,
            s.minibatch,
            s.stop_accuracy,
            self.generator,
            sync_every_step=s.sync_every_step,
            learner=self.learner,
            stop_pairs=counted,
        )

    def relabel(self) -> None:
        """Every stored transition gets the current model's reward."""
        self.replay.relabel(self.model.reward, chunk=self.settings.relabel_chunk)

    def quality(self, run_seed: int, session: int) -> dict[str, float]:
        s = self.settings
        rng = np.random.default_rng([run_seed, 2, session])
        return reward_quality(
            self.model, self.episodes, self.replay, s.heldout_pairs, s.segment_length, rng
        )
