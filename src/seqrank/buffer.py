"""The replay buffer: a ring of transitions on the host or the training device.

The replay buffer keeps the true reward beside the learned one, so the learned reward can
be recomputed for every stored transition after each reward update, also after the ring
has wrapped (the reference code only relabels up to the write index).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import torch

RewardFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


@dataclass(frozen=True)
class Batch:
    obs: torch.Tensor
    action: torch.Tensor
    reward: torch.Tensor  # the reward trained on (learned, or true for the baseline), (B, 1)
    next_obs: torch.Tensor
    not_done: torch.Tensor  # 0 only at true terminals; time limits are not terminal


class BatchSource(Protocol):
    """Where an agent's hot-loop update draws its batch: the replay buffer itself, or a
    view of it that mixes in recent transitions (`agents.hybrid_replay`)."""

    @property
    def storage(self) -> torch.device:
        """Where the transitions live (a captured update needs the training device)."""
        ...

    def sample(self, batch_size: int, generator: torch.Generator) -> Batch:
        """A batch, its indices drawn from the host generator."""
        ...

    def sample_on_device(self, batch_size: int) -> Batch:
        """A batch, its indices drawn where the table lives (capturable in a CUDA graph)."""
        ...


class RewardTable(Protocol):
    """Stored transitions whose learned reward follows the reward model: seqrank's replay
    buffer, or another agent's (`seqrank.sb3`)."""

    def relabel(self, reward_fn: RewardFn, chunk: int = 8192) -> None:
        """Recompute the learned reward of every stored transition."""
        ...

    def reward_sample(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(learned, true) per-step rewards of up to `count` stored transitions drawn
        without replacement."""
        ...


STAGING_ROWS = 16  # pinned host rows the fast path's adds cycle through
COLUMNS = ("obs", "action", "next_obs", "true_reward", "reward", "not_done")


class ReplayBuffer:
    """A ring of transitions in one table: a row is obs | action | next_obs | true reward |
    learned reward | not_done, so a batch is one gather and a transition one copy.

    `storage` is where the table lives: the host for the reference path (each batch is
    then copied to `device`, as the field's research code does), the device for the fast
    path. `size_t` and `index_t` mirror the size and the write index on the storage
    device, so sampling can run inside a CUDA graph without reading them back.
    """

    @staticmethod
    def row_width(obs_dim: int, act_dim: int) -> int:
        """Floats per stored transition: obs | action | next_obs | two rewards | not_done."""
        return 2 * obs_dim + act_dim + 3

    def __init__(
        self,
        capacity: int,
        obs_dim: int,
        act_dim: int,
        device: torch.device,
        storage: torch.device | None = None,
        train_on: str = "reward",
    ):
        """`train_on` is the reward column that batches carry: `reward` (learned) or
        `true_reward` (the true-reward baseline)."""
        if train_on not in ("reward", "true_reward"):
            raise ValueError(f"train_on {train_on!r}; accepted: reward, true_reward")
        self.capacity, self.device, self.train_on = capacity, device, train_on
        self.storage = storage if storage is not None else device
        widths = (obs_dim, act_dim, obs_dim, 1, 1, 1)
        self.width = self.row_width(obs_dim, act_dim)
        self.table = torch.zeros((capacity, self.width), dtype=torch.float32, device=self.storage)
        offsets = np.cumsum((0, *widths))
        self.columns = {
            name: slice(int(a), int(b))
            for name, a, b in zip(COLUMNS, offsets[:-1], offsets[1:], strict=True)
        }
        for name, cols in self.columns.items():
            setattr(self, name, self.table[:, cols])
        self.obs: torch.Tensor
        self.action: torch.Tensor
        self.next_obs: torch.Tensor
        self.true_reward: torch.Tensor
        self.reward: torch.Tensor
        self.not_done: torch.Tensor
        self.size_t = torch.zeros((), dtype=torch.float32, device=self.storage)
        self.index_t = torch.zeros((), dtype=torch.long, device=self.storage)
        self.index, self.size = 0, 0
        self._staging: torch.Tensor | None = None
        self._staging_events: dict[int, Any] = {}
        self._staged = 0

    def __len__(self) -> int:
        return self.size

    def row(
        self,
        obs: np.ndarray,
        action: np.ndarray,
        true_reward: float,
        learned_reward: float,
        next_obs: np.ndarray,
        terminated: bool,
    ) -> np.ndarray:
        tail = (true_reward, learned_reward, 0.0 if terminated else 1.0)
        return np.concatenate([obs, action, next_obs, tail], dtype=np.float32)

    def add(
        self,
        obs: np.ndarray,
        action: np.ndarray,
        true_reward: float,
        learned_reward: float,
        next_obs: np.ndarray,
        terminated: bool,
    ) -> None:
        row = self.row(obs, action, true_reward, learned_reward, next_obs, terminated)
        self.write_row(torch.from_numpy(row))

    def add_transition(
        self,
        obs: np.ndarray,
        action: np.ndarray,
        true_reward: float,
        next_obs: np.ndarray,
        terminated: bool,
        reward_fn: RewardFn | None,
    ) -> None:
        """A transition as the loop stores it, its learned reward computed by `reward_fn`
        on the stored row (none before the first reward model). On CUDA the row goes
        through a ring of pinned host rows with one asynchronous copy, and the learned
        reward is computed on the device (no host round trip)."""
        i = self.index
        row = self.row(obs, action, true_reward, 0.0, next_obs, terminated)
        if self.storage.type == "cuda":
            self._write_staged(row)
        else:
            self.write_row(torch.from_numpy(row))
        if reward_fn is not None:
            with torch.no_grad():
                obs_t, action_t = self.obs[i : i + 1], self.action[i : i + 1]
                learned = reward_fn(obs_t.to(self.device), action_t.to(self.device))
                self.reward[i : i + 1] = learned.to(self.storage)

    def _write_staged(self, row: np.ndarray) -> None:
        if self._staging is None:
            self._staging = torch.zeros((STAGING_ROWS, self.width), pin_memory=True)
        k = self._staged % STAGING_ROWS
        self._staged += 1
        event = self._staging_events.get(k)
        if event is not None:  # a pinned row is rewritten only once its copy is done
            event.synchronize()
        slot = self._staging[k]
        slot.numpy()[:] = row
        self.write_row(slot)
        self._staging_events[k] = torch.cuda.Event()
        self._staging_events[k].record()

    def write_row(self, row: torch.Tensor) -> None:
        self.table[self.index].copy_(row, non_blocking=True)
        self.index = (self.index + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)
        self.size_t.fill_(self.size)
        self.index_t.fill_(self.index)

    def _batch(self, rows: torch.Tensor) -> Batch:
        cols = self.columns
        return Batch(
            rows[:, cols["obs"]],
            rows[:, cols["action"]],
            rows[:, cols[self.train_on]],
            rows[:, cols["next_obs"]],
            rows[:, cols["not_done"]],
        )

    def sample(self, batch_size: int, generator: torch.Generator) -> Batch:
        """Indices from the host generator; the reference path copies the batch to `device`."""
        return self.gather(torch.randint(0, self.size, (batch_size,), generator=generator))

    def gather(self, idx: torch.Tensor) -> Batch:
        """The rows at `idx` as a batch on the training device."""
        return self._batch(self.table[idx.to(self.storage)].to(self.device))

    def sample_on_device(self, batch_size: int) -> Batch:
        """Indices drawn where the table lives, from `size_t`: no host value is read, so
        this can be captured in a CUDA graph. Requires storage on the training device."""
        draw = torch.rand(batch_size, device=self.storage) * self.size_t
        idx = draw.long().clamp_(max=self.capacity - 1)
        return self._batch(self.table[idx])

    def relabel(self, reward_fn: RewardFn, chunk: int = 8192) -> None:
        """Recompute the learned reward of every stored transition (the whole ring), in
        chunks on the training device."""
        with torch.no_grad():
            for start in range(0, self.size, chunk):
                stop = min(start + chunk, self.size)
                obs = self.obs[start:stop].to(self.device)
                action = self.action[start:stop].to(self.device)
                self.reward[start:stop] = reward_fn(obs, action).to(self.storage)

    def reward_sample(self, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        idx = rng.choice(self.size, size=min(self.size, count), replace=False)
        return self.reward[idx, 0].cpu().numpy(), self.true_reward[idx, 0].cpu().numpy()

    def state_dict(self) -> dict[str, Any]:
        n = self.size
        state: dict[str, Any] = {"index": self.index, "size": n}
        for name in COLUMNS:  # compact host copies, not views of the whole table
            state[name] = getattr(self, name)[:n].to("cpu", copy=True).contiguous()
        return state

    def load_state_dict(self, state: dict[str, Any]) -> None:
        n = state["size"]
        for name in COLUMNS:
            getattr(self, name)[:n] = state[name].to(self.storage)
        self.index, self.size = state["index"], n
        self.size_t.fill_(n)
        self.index_t.fill_(self.index)
