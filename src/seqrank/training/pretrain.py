"""Unsupervised pre-training (PEBBLE): the agent learns from a state-entropy reward, the
distance of each state to its k-th nearest neighbour among the stored states. With
`warm_start` (RIME's), the reward model is fitted to that reward too (`reward.warm_start`)."""

from __future__ import annotations

import torch

from seqrank.agents.protocol import Agent
from seqrank.buffer import Batch, ReplayBuffer
from seqrank.reward.entropy import RunningMeanStd, intrinsic_reward, knn_distance
from seqrank.reward.model import RewardModel
from seqrank.reward.warm_start import UPDATES_PER_STEP, fit_intrinsic, warm_start_target


class EntropyPretraining:
    def __init__(
        self,
        agent: Agent,
        replay: ReplayBuffer,
        batch: int,
        knn_k: int,
        device: torch.device,
        generator: torch.Generator,
        warm_start: RewardModel | None = None,
    ):
        self.agent, self.replay, self.batch, self.knn_k = agent, replay, batch, knn_k
        self.device, self.generator = device, generator
        self.stats = RunningMeanStd()  # normalises the intrinsic reward; checkpointed
        self.warm_start = warm_start  # the reward model to fit to the intrinsic reward

    def update(self) -> None:
        batch = self.replay.sample(self.batch, self.generator)
        stored = self.replay.obs[: len(self.replay)].to(self.device)
        reward = intrinsic_reward(batch.obs, stored, self.knn_k, self.stats)
        batch = Batch(batch.obs, batch.action, reward, batch.next_obs, batch.not_done)
        self.agent.update(batch, self.generator)
        if self.warm_start is not None:
            self.fit_reward_model(self.warm_start, stored)

    def fit_reward_model(self, model: RewardModel, stored: torch.Tensor) -> None:
        """RIME's warm start: a few steps towards the intrinsic reward of fresh batches
        (the statistics are read, not updated: the agent's reward stays as it was)."""
        for _ in range(UPDATES_PER_STEP):
            batch = self.replay.sample(self.batch, self.generator)
            distance = knn_distance(batch.obs, stored, self.knn_k)
            target = warm_start_target(distance, self.stats)
            fit_intrinsic(model, batch.obs, batch.action, target)
