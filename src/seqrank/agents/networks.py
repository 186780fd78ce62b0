"""The network every agent is built from: an MLP with orthogonal weights (SAC, DQN, IQL)."""

from __future__ import annotations

import itertools

from torch import nn


def mlp(inputs: int, hidden: int, layers: int, outputs: int) -> nn.Sequential:
    """`layers` hidden ReLU layers; orthogonal weights, zero biases."""
    sizes = [inputs] + [hidden] * layers + [outputs]
    modules: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes):
        modules += [nn.Linear(a, b), nn.ReLU()]
    net = nn.Sequential(*modules[:-1])
    orthogonal_init(net)
    return net


def orthogonal_init(net: nn.Module) -> None:
    for module in net.modules():
        if isinstance(module, nn.Linear):
            nn.init.orthogonal_(module.weight)
            nn.init.zeros_(module.bias)
