"""How good is the policy, and how good is the learned reward."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from seqrank.agents.protocol import Policy
from seqrank.buffer import RewardTable
from seqrank.envs import SimEnv
from seqrank.episodes import EpisodeStore
from seqrank.reward.model import RewardModel

CORRELATION_SAMPLE = 20_000


@dataclass(frozen=True)
class PolicyScore:
    returns: list[float]
    successes: list[bool]  # the episode reached info["success"] at some step


def evaluate_policy(
    agent: Policy, env: SimEnv, seeds: list[int], generator: torch.Generator
) -> PolicyScore:
    """One episode per seed with the deterministic action (tanh of the mean)."""
    returns, successes = [], []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        total, success, done = 0.0, False, False
        while not done:
            obs, reward, terminated, truncated, info = env.step(agent.act(obs, True, generator))
            total += float(reward)
            success = success or bool(info["success"])
            done = terminated or truncated
        returns.append(total)
        successes.append(success)
    return PolicyScore(returns, successes)


def reward_quality(
    reward_model: RewardModel,
    episodes: EpisodeStore,
    replay: RewardTable,
    pairs: int,
    segment_length: int,
    rng: np.random.Generator,
) -> dict[str, float]:
    """Held-out accuracy on true preferences of fresh random segment pairs, and the
    Pearson correlation of learned and true per-step reward over a sample of the replay
    buffer."""
    sample = episodes.sample_segments(2 * pairs, segment_length, rng)
    predicted = reward_model.member_returns(sample.features).mean(0)
    truth = sample.rewards.sum(1)
    a, b = np.arange(0, len(truth), 2), np.arange(1, len(truth), 2)
    strict = truth[a] != truth[b]
    agree = (predicted[a] > predicted[b]) == (truth[a] > truth[b])
    learned, true = replay.reward_sample(CORRELATION_SAMPLE, rng)
    corr = float(np.corrcoef(learned, true)[0, 1]) if learned.std() and true.std() else 0.0
    return {
        "reward_heldout_accuracy": float(agree[strict].mean()) if strict.any() else 1.0,
        "reward_correlation": corr,
    }
