"""SAC's twin critics in two layouts, and one checkpoint layout for both.

`TwinCritic` keeps each critic an `nn.Sequential` of `nn.Linear` layers (the reference
path); `StackedTwinCritic` stacks both critics' weights on a leading axis of 2, so each
layer of both is one batched matmul (the fast path). They compute the same function; a
checkpoint always stores the `TwinCritic` layout ("canonical"), so a run saved on one path
resumes on the other.
"""

from __future__ import annotations

import itertools

import torch
from torch import nn

from seqrank.agents.networks import mlp, orthogonal_init

Canonical = dict[str, torch.Tensor]


class TwinCritic(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int, hidden: int, layers: int):
        super().__init__()
        self.q1 = mlp(obs_dim + act_dim, hidden, layers, 1)
        self.q2 = mlp(obs_dim + act_dim, hidden, layers, 1)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([obs, action], dim=-1)
        return self.q1(x), self.q2(x)

    @torch.no_grad()
    def reinitialise(self) -> None:
        """As constructing a new one: the same draws from torch's global generator."""
        for net in (self.q1, self.q2):
            for module in net:
                if isinstance(module, nn.Linear):
                    module.reset_parameters()
            orthogonal_init(net)

    def to_canonical(self, tensors: list[torch.Tensor]) -> Canonical:
        names = [name for name, _ in self.named_parameters()]
        return dict(zip(names, tensors, strict=True))

    def from_canonical(self, canonical: Canonical) -> list[torch.Tensor]:
        return [canonical[name] for name, _ in self.named_parameters()]


class StackedTwinCritic(nn.Module):
    """Both critics as weights stacked over a leading axis of 2; ReLU hidden layers."""

    def __init__(self, obs_dim: int, act_dim: int, hidden: int, layers: int):
        super().__init__()
        sizes = [obs_dim + act_dim] + [hidden] * layers + [1]
        self.weights = nn.ParameterList(
            nn.Parameter(torch.empty(2, a, b)) for a, b in itertools.pairwise(sizes)
        )
        self.biases = nn.ParameterList(
            nn.Parameter(torch.zeros(2, 1, b)) for b in itertools.islice(sizes, 1, None)
        )
        self.reinitialise()

    @torch.no_grad()
    def reinitialise(self) -> None:
        """Orthogonal weights and zero biases per critic, like `mlp`, in place."""
        for weight, bias in zip(self.weights, self.biases, strict=True):
            for member in weight:
                member.copy_(nn.init.orthogonal_(torch.empty(member.shape[::-1])).T)
            bias.zero_()

    def stacked(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """Q-values of both critics, (2, B, 1)."""
        x = torch.cat([obs, action], dim=-1).unsqueeze(0).expand(2, -1, -1)
        last = len(self.weights) - 1
        for i, (weight, bias) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = torch.baddbmm(bias, x, weight)
            if i < last:
                x = torch.relu(x)
        return x

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        q = self.stacked(obs, action)
        return q[0], q[1]

    def to_canonical(self, tensors: list[torch.Tensor]) -> Canonical:
        """nn.Linear stores a weight as (out, in); this layout as (in, out) per critic."""
        layers = len(self.weights)
        weights, biases = tensors[:layers], tensors[layers:]
        canonical: Canonical = {}
        for critic in range(2):
            for layer in range(layers):
                prefix = f"q{critic + 1}.{2 * layer}"
                canonical[f"{prefix}.weight"] = weights[layer][critic].T.contiguous()
                canonical[f"{prefix}.bias"] = biases[layer][critic, 0].clone()
        return canonical

    def from_canonical(self, canonical: Canonical) -> list[torch.Tensor]:
        layers = range(len(self.weights))
        weights = [
            torch.stack([canonical[f"q{c}.{2 * i}.weight"].T for c in (1, 2)]) for i in layers
        ]
        biases = [
            torch.stack([canonical[f"q{c}.{2 * i}.bias"][None] for c in (1, 2)]) for i in layers
        ]
        return weights + biases


Critic = TwinCritic | StackedTwinCritic


def canonical_weights(critic: Critic) -> Canonical:
    return {
        k: v.detach().clone() for k, v in critic.to_canonical(list(critic.parameters())).items()
    }


@torch.no_grad()
def load_canonical_weights(critic: Critic, canonical: Canonical) -> None:
    for param, value in zip(critic.parameters(), critic.from_canonical(canonical), strict=True):
        param.copy_(value)
