"""The parts of a run that learn from feedback, made from its config: the reward model,
the sessions (when, how many, cut how), and reward learning. seqrank's `Trainer` and
other agents' runs (`seqrank.sb3`) build them here, so both learn alike."""

from __future__ import annotations

import numpy as np
import torch

from seqrank.buffer import RewardTable
from seqrank.config import TrainConfig
from seqrank.episodes import EpisodeStore
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.session import FeedbackSource, SessionPlan
from seqrank.reward.learners import make_learner
from seqrank.reward.model import RewardModel
from seqrank.reward.rime import RimeSettings
from seqrank.reward.surf import SurfSettings
from seqrank.training.reward_phase import RewardLearning, RewardSettings
from seqrank.training.sessions import FeedbackSessions, Schedule


def teacher_source(config: TrainConfig) -> FeedbackSource:
    """The source `config.teacher` names, with a crowd's evidence settings (the overlap,
    its adaptive part, closure checks); ValueError for `human` (the page brings its own)."""
    from seqrank.feedback.sources import make_source

    checks = bool(config.closure_checks)
    return make_source(config.teacher, config.overlap, config.overlap_until, checks)


def session_plan(config: TrainConfig) -> SessionPlan:
    """How the run's sessions are cut, chosen and checked."""
    return SessionPlan(
        config.scheme.value,
        config.selection.value,
        config.oversample,
        config.segment_length,
        recheck=config.recheck,
        query_episodes=config.query_episodes,
        crowd=len(config.team),
        order=config.segment_order.value,
    )


def make_reward_model(config: TrainConfig, features: int, device: torch.device) -> RewardModel:
    """The ensemble over `features` inputs (observation and action)."""
    return RewardModel(
        config.reward_ensemble,
        features,
        config.reward_hidden,
        config.reward_layers,
        config.reward_lr,
        device,
    )


def make_sessions(
    config: TrainConfig,
    source: FeedbackSource,
    episodes: EpisodeStore,
    reward_model: RewardModel,
    rng: np.random.Generator,
    labels: LabelStore,
    episode_length: int,
    wait_for_feedback: bool,
) -> FeedbackSessions:
    schedule = Schedule(
        config.max_feedback, config.reward_batch, config.feedback_frequency, episode_length
    )
    return FeedbackSessions(
        schedule,
        session_plan(config),
        source,
        episodes,
        reward_model,
        rng,
        wait_for_feedback,
        labels,
    )


def make_reward_learning(
    config: TrainConfig,
    reward_model: RewardModel,
    labels: LabelStore,
    table: RewardTable,
    episodes: EpisodeStore,
    generator: torch.Generator,
    fast: bool,
) -> RewardLearning:
    """Reward learning with the config's learner (plain, SURF, RIME); `fast` reads the loss
    back per epoch and relabels in larger chunks."""
    settings = RewardSettings(
        config.reward_epochs,
        config.reward_minibatch,
        config.reward_stop_accuracy,
        config.heldout_pairs,
        config.segment_length,
        sync_every_step=not fast,
        relabel_chunk=65_536 if fast else 8_192,
        stop_on=config.reward_stop_on,
    )
    learner = make_learner(
        config.reward_learner,
        generator,
        SurfSettings(
            config.surf_threshold,
            config.surf_unlabelled_ratio,
            config.surf_unlabelled_batch,
            config.surf_loss_weight,
            config.surf_crop,
        ),
        RimeSettings(
            config.rime_alpha,
            config.rime_beta_max,
            config.rime_beta_min,
            config.rime_decay_updates,
            config.rime_tau_upper,
            config.rime_min_epochs,
        ),
    )
    return RewardLearning(reward_model, labels, table, episodes, settings, generator, learner)
