"""`PreferenceReplayBuffer`: the replay buffer of an off-policy agent that pre-trains, made
by SB3 from the class passed as `replay_buffer_class` (SB3's seam for a buffer):

    SAC("MlpPolicy", feedback.env, replay_buffer_class=PreferenceReplayBuffer)

It is SB3's `ReplayBuffer`, but while the feedback pre-trains (PEBBLE's unsupervised phase,
until the first session) each batch it samples carries the state-entropy reward instead of
the stored one. That reward is part of the buffer, not a method patched onto it, so SB3's
own savers (`save_replay_buffer`, `CheckpointCallback(save_replay_buffer=True)`) pickle it
at any step, and a buffer saved during pre-training loads and samples the same reward.
"""

from __future__ import annotations

from typing import Any

import torch
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.type_aliases import ReplayBufferSamples

from seqrank.reward.entropy import RunningMeanStd, intrinsic_reward


class EntropyReward:
    """PEBBLE's state-entropy reward of a batch: each observation's distance to its k-th
    nearest stored one, over the running standard deviation of those distances
    (`reward.entropy`)."""

    def __init__(self, knn_k: int, stats: RunningMeanStd):
        self.knn_k, self.stats = knn_k, stats

    def __call__(self, observations: torch.Tensor, stored: torch.Tensor) -> torch.Tensor:
        queries = observations.reshape(len(observations), -1).float()
        return intrinsic_reward(queries, stored.to(queries.device), self.knn_k, self.stats)


class PreferenceReplayBuffer(ReplayBuffer):
    """SB3's `ReplayBuffer` whose batches carry `entropy`'s reward while it is set (by
    `PreferenceFeedback`, from the start of training to the first session); otherwise the
    stored, relabelled rewards, as SB3's own buffer gives them.

    Args:
        *args: SB3's `ReplayBuffer` arguments (SB3 passes them: give the class as the
            agent's `replay_buffer_class`).
        **kwargs: SB3's `ReplayBuffer` keywords (`replay_buffer_kwargs`).

    Attributes:
        entropy: the state-entropy reward while pre-training, else None.

    Examples:
        >>> from stable_baselines3 import SAC
        >>> from seqrank.sb3 import PreferenceFeedback, PreferenceReplayBuffer
        >>> feedback = PreferenceFeedback("gym:Pendulum-v1")
        >>> model = SAC("MlpPolicy", feedback.env, replay_buffer_class=PreferenceReplayBuffer)
        >>> type(model.replay_buffer).__name__, model.replay_buffer.entropy
        ('PreferenceReplayBuffer', None)
    """

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.entropy: EntropyReward | None = None

    def sample(self, batch_size: int, env: Any = None) -> ReplayBufferSamples:
        batch = super().sample(batch_size, env)
        if self.entropy is None:
            return batch
        reward = self.entropy(batch.observations, self.stored_observations())
        return batch._replace(rewards=reward.reshape(-1, 1).to(batch.rewards.dtype))

    def stored_observations(self) -> torch.Tensor:
        """Every stored observation, (rows, obs_dim)."""
        size = self.buffer_size if self.full else self.pos
        obs = self.observations[:size]
        return torch.as_tensor(obs.reshape(-1, obs.shape[-1]), dtype=torch.float32)
