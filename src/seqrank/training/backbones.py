"""The agent update of each step after the first session, by backbone: PEBBLE is the
agent's own update; MRN wraps it with a meta reward step (`agents.mrn`). A new backbone is
registered in `BACKBONES`; the loop does not change. Either backbone draws its batches
through QPA's hybrid replay (`agents.hybrid_replay`) while feedback is asked for, when
`hybrid_replay` is above 0; SAC and DQN alike, since both sample through `update_from`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import torch

from seqrank.agents.hybrid_replay import HybridReplay
from seqrank.agents.mrn import MetaRewardUpdate, MetaSettings, PairBatch
from seqrank.agents.protocol import Agent
from seqrank.agents.sac import SAC
from seqrank.buffer import BatchSource, ReplayBuffer
from seqrank.config import TrainConfig
from seqrank.feedback.labels import LabelStore
from seqrank.reward.model import RewardModel


class AgentUpdate(Protocol):
    def __call__(self, step: int, feedback_open: bool) -> None:
        """One step's learning; `feedback_open` while feedback is still being asked for."""


@dataclass(frozen=True)
class UpdateParts:
    agent: Agent
    replay: ReplayBuffer
    reward_model: RewardModel
    labels: LabelStore
    relabel: Callable[[], None]
    record: Callable[[str, float], None]  # an extra metric for the next `train` row
    obs_dim: int
    generator: torch.Generator
    episode_length: int  # the task's, for the hybrid replay's window in episodes


def hybrid_replay(config: TrainConfig, parts: UpdateParts) -> HybridReplay | None:
    """QPA's hybrid replay over the run's buffer; None when `hybrid_replay` is 0 (off)."""
    if config.hybrid_replay == 0:
        return None
    window = config.hybrid_episodes * parts.episode_length
    return HybridReplay(parts.replay, config.hybrid_replay, window)


def logging_hybrid(
    update: AgentUpdate, hybrid: HybridReplay | None, batch: int, parts: UpdateParts
) -> AgentUpdate:
    """`update`, recording for the `train` rows the share of recent rows in its batches (0
    once feedback is closed) and the recent window's transitions; unchanged when off."""
    if hybrid is None:
        return update
    share = hybrid.recent_rows(batch) / batch

    def logged(step: int, feedback_open: bool) -> None:
        parts.record("hybrid_recent_share", share if feedback_open else 0.0)
        parts.record("hybrid_window", float(hybrid.window_rows()))
        update(step, feedback_open)

    return logged


def pebble_update(config: TrainConfig, parts: UpdateParts) -> AgentUpdate:
    hybrid = hybrid_replay(config, parts)

    def update(step: int, feedback_open: bool) -> None:
        source: BatchSource = parts.replay
        if feedback_open and hybrid is not None:
            source = hybrid
        parts.agent.update_from(source, config.batch, parts.generator)

    return logging_hybrid(update, hybrid, config.batch, parts)


def mrn_update(config: TrainConfig, parts: UpdateParts) -> AgentUpdate:
    if not isinstance(parts.agent, SAC):
        raise ValueError("backbone 'mrn' needs SAC's critic; use backbone pebble")
    device, obs_dim = parts.reward_model.device, parts.obs_dim

    def recent_pairs() -> PairBatch | None:
        """The last session's labelled pairs, scored by their segments' first step."""
        if not len(parts.labels):
            return None
        segments, first, second, labels = parts.labels.tensors(device, last=config.reward_batch)
        a, b = segments[first][:, 0], segments[second][:, 0]
        return PairBatch(a[:, :obs_dim], a[:, obs_dim:], b[:, :obs_dim], b[:, obs_dim:], labels)

    settings = MetaSettings(config.batch, config.meta_update_frequency, config.meta_loss_weight)
    hybrid = hybrid_replay(config, parts)
    meta = MetaRewardUpdate(
        parts.agent,
        parts.reward_model,
        parts.replay,
        settings,
        recent_pairs,
        parts.relabel,
        parts.generator,
        parts.record,
        hybrid,
    )
    return logging_hybrid(meta, hybrid, config.batch, parts)


BACKBONES: dict[str, Callable[[TrainConfig, UpdateParts], AgentUpdate]] = {
    "pebble": pebble_update,
    "mrn": mrn_update,
}
