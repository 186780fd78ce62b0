"""QPA's hybrid experience replay (Hu et al., "Query-Policy Misalignment in Preference-Based
Reinforcement Learning", ICLR 2024): while feedback is still being asked for,
each agent batch takes a fixed share of its rows from the most recent transitions (those
of the current policy, which the policy-aligned queries also come from) and the rest
uniformly from the whole replay buffer, so the critic is fitted where the learned reward
is most accurate.

Defaults here are off; the values QPA ran with (its code, github.com/huxiao09/QPA):
- `hybrid_replay` 0.5, the share of recent rows: `her_ratio=0.5` in `config/train_QPA.yaml`
  and every task of `run_QPA.sh`, used by `update_onpolicy_sample` in `agent/sac.py`;
- `hybrid_episodes` 10, the recent window in episodes of the task's length: the window is
  `max_reward_buffer_size` episodes of `max_episode_len` steps (`sample_onpolicy` in
  `replay_buffer.py`), 10 on DMControl in `run_QPA.sh` (30 or 60 on its Meta-World tasks);
- hybrid batches only while feedback remains, plain uniform ones after the last session
  (`train_QPA.py`); the critic reset's updates and pre-training stay uniform.
Unlike QPA's two draws rounded down (which can shrink the batch), the recent rows are
`round(share * batch)` and the rest uniform, so the batch keeps its size.
"""

from __future__ import annotations

import torch

from seqrank.buffer import Batch, ReplayBuffer


class HybridReplay:
    """A `BatchSource` over `replay`: `recent_rows(batch)` rows from its last `window`
    stored transitions (fewer while it holds fewer), the rest from all of it. The recent
    rows come last in the batch."""

    def __init__(self, replay: ReplayBuffer, share: float, window: int):
        if not 0.0 <= share <= 1.0 or window < 1:
            raise ValueError(f"hybrid replay share {share} in [0, 1], window {window} >= 1")
        self.replay, self.share, self.window = replay, share, window

    @property
    def storage(self) -> torch.device:
        return self.replay.storage

    def recent_rows(self, batch_size: int) -> int:
        return round(self.share * batch_size)

    def window_rows(self) -> int:
        """How many transitions the recent window holds now."""
        return min(self.window, len(self.replay))

    def indices(self, batch_size: int, generator: torch.Generator) -> torch.Tensor:
        """Row indices from the host generator: uniform ones, then recent ones."""
        r = self.replay
        recent = self.recent_rows(batch_size)
        uniform = torch.randint(0, r.size, (batch_size - recent,), generator=generator)
        back = torch.randint(0, self.window_rows(), (recent,), generator=generator)
        return torch.cat([uniform, (r.index - 1 - back) % r.capacity])

    def device_indices(self, batch_size: int) -> torch.Tensor:
        """The same draw where the table lives, from the buffer's size and write index
        mirrored there: no host value is read, so a CUDA graph can capture it."""
        r, device = self.replay, self.replay.storage
        recent = self.recent_rows(batch_size)
        size = r.size_t
        uniform = (torch.rand(batch_size - recent, device=device) * size).long()
        window = size.clamp(max=self.window)
        back = torch.minimum((torch.rand(recent, device=device) * window).long(), window.long() - 1)
        idx = torch.cat([uniform.clamp_(max=r.capacity - 1), r.index_t - 1 - back])
        return torch.remainder(idx, r.capacity)

    def sample(self, batch_size: int, generator: torch.Generator) -> Batch:
        return self.replay.gather(self.indices(batch_size, generator))

    def sample_on_device(self, batch_size: int) -> Batch:
        return self.replay.gather(self.device_indices(batch_size))
