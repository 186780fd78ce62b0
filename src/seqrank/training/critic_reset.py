"""PEBBLE's critic reset after the first reward model: the value function learned from the
entropy reward is forgotten, the policy kept, and the new critic gets a head start of
`updates` updates on the relabelled buffer."""

from __future__ import annotations

import torch

from seqrank.agents.protocol import Agent
from seqrank.buffer import ReplayBuffer


def reset_critic(
    agent: Agent, replay: ReplayBuffer, updates: int, batch: int, generator: torch.Generator
) -> None:
    agent.reset_critic()
    for _ in range(updates):
        agent.update(replay.sample(batch, generator), generator)
