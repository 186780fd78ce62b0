"""Unsupervised pre-training (PEBBLE): the agent learns from a state-entropy reward, the
distance of each state to its k-th nearest neighbour among the stored states."""

from __future__ import annotations

import torch

from seqrank.agents.protocol import Agent
from seqrank.buffer import Batch, ReplayBuffer
from seqrank.reward.entropy import RunningMeanStd, intrinsic_reward


class EntropyPretraining:
    def __init__(
        self,
        agent: Agent,
        replay: ReplayBuffer,
        batch: int,
        knn_k: int,
        device: torch.device,
        generator: torch.Generator,
    ):
        self.agent, self.replay, self.batch, self.knn_k = agent, replay, batch, knn_k
        self.device, self.generator = device, generator
        self.stats = RunningMeanStd()  # normalises the intrinsic reward; checkpointed

    def update(self) -> None:
        batch = self.replay.sample(self.batch, self.generator)
        stored = self.replay.obs[: len(self.replay)].to(self.device)
        reward = intrinsic_reward(batch.obs, stored, self.knn_k, self.stats)
        batch = Batch(batch.obs, batch.action, reward, batch.next_obs, batch.not_done)
        self.agent.update(batch, self.generator)
