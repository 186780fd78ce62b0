"""The feedback side of an SB3 run: seqrank's own parts (`training.feedback_parts`) made
from the run config, the counters and both random streams, and their saved state."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from seqrank.buffer import RewardTable
from seqrank.config import TrainConfig
from seqrank.episodes import EpisodeStore
from seqrank.feedback.labels import LabelStore
from seqrank.feedback.session import FeedbackSource
from seqrank.reward.entropy import RunningMeanStd
from seqrank.sb3.tables import EpisodeTable
from seqrank.training.feedback_parts import (
    make_reward_learning,
    make_reward_model,
    make_sessions,
)
from seqrank.training.state import Counters


class FeedbackRun:
    def __init__(
        self,
        config: TrainConfig,
        source: FeedbackSource,
        obs_dim: int,
        act_dim: int,
        episode_length: int,
        device: torch.device,
        wait_for_feedback: bool,
    ):
        self.config, self.source, self.device = config, source, device
        self.obs_dim, self.act_dim = obs_dim, act_dim
        torch.manual_seed(config.seed)  # the reward model's initial weights, as in a run
        self.reward_model = make_reward_model(config, obs_dim + act_dim, device)
        self.episodes = EpisodeStore(config.episodes_kept)
        self.labels = LabelStore(config.crowd_weighting.value)
        self.rng = np.random.default_rng(np.random.SeedSequence(config.seed))
        self.generator = torch.Generator().manual_seed(config.seed)
        self.counters = Counters()
        self.entropy_stats = RunningMeanStd()
        self.sessions = make_sessions(
            config,
            source,
            self.episodes,
            self.reward_model,
            self.rng,
            self.labels,
            episode_length,
            wait_for_feedback,
        )
        table = EpisodeTable(self.episodes, self.reward_model.reward, device)
        self.reward = make_reward_learning(
            config, self.reward_model, self.labels, table, self.episodes, self.generator, False
        )

    def use_table(self, table: RewardTable) -> None:
        """Where relabelling writes and reward quality reads (the agent's, once known)."""
        self.reward.replay = table

    @torch.no_grad()
    def learned_reward(self, obs: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """The ensemble mean of each (observation, canonical action); 0 before the first
        session, as a seqrank run stores it."""
        if self.counters.sessions == 0:
            return np.zeros(len(obs), np.float32)
        obs_t = torch.as_tensor(obs, dtype=torch.float32, device=self.device)
        act_t = torch.as_tensor(actions, dtype=torch.float32, device=self.device)
        return self.reward_model.reward(obs_t, act_t).reshape(-1).cpu().numpy()

    def state_dict(self) -> dict[str, Any]:
        return {
            "counters": self.counters.state_dict(),
            "reward_model": self.reward_model.state_dict(),
            "reward_learner": self.reward.learner.state_dict(),
            "episodes": self.episodes.state_dict(),
            "labels": self.labels.state_dict(),
            "entropy_stats": self.entropy_stats.state_dict(),
            "rng": self.rng.bit_generator.state,
            "generator": self.generator.get_state(),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        for name, value in state["counters"].items():
            setattr(self.counters, name, value)
        self.reward_model.load_state_dict(state["reward_model"])
        self.reward.learner.load_state_dict(state["reward_learner"])
        self.episodes.load_state_dict(state["episodes"])
        self.labels.load_state_dict(state["labels"])
        self.entropy_stats.load_state_dict(state["entropy_stats"])
        self.rng.bit_generator.state = state["rng"]
        self.generator.set_state(state["generator"])
