"""The steps every agent's update is made of (SAC, DQN, IQL): one optimiser step on a
loss, and the soft update of a target network."""

from __future__ import annotations

from collections.abc import Iterable

import torch


def descend(optimizer: torch.optim.Optimizer, loss: torch.Tensor) -> None:
    """One optimiser step on `loss`."""
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    optimizer.step()


@torch.no_grad()
def soft_update(target: Iterable[torch.Tensor], source: Iterable[torch.Tensor], tau: float) -> None:
    """target <- (1 - tau) target + tau source, for every tensor at once."""
    torch._foreach_lerp_(list(target), list(source), tau)
