"""The agent update of each step after the first session, by backbone: PEBBLE is the
agent's own update; MRN wraps it with a meta reward step (`agents.mrn`). A new backbone is
registered in `BACKBONES`; the loop does not change."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import torch

from seqrank.agents.mrn import MetaRewardUpdate, MetaSettings, PairBatch
from seqrank.agents.protocol import Agent
from seqrank.agents.sac import SAC
from seqrank.buffer import ReplayBuffer
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


def pebble_update(config: TrainConfig, parts: UpdateParts) -> AgentUpdate:
    def update(step: int, feedback_open: bool) -> None:
        parts.agent.update_from(parts.replay, config.batch, parts.generator)

    return update


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
    return MetaRewardUpdate(
        parts.agent,
        parts.reward_model,
        parts.replay,
        settings,
        recent_pairs,
        parts.relabel,
        parts.generator,
        parts.record,
    )


BACKBONES: dict[str, Callable[[TrainConfig, UpdateParts], AgentUpdate]] = {
    "pebble": pebble_update,
    "mrn": mrn_update,
}
