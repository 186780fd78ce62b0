"""SAC's actor: a squashed Gaussian over an MLP (`agents.networks.mlp`), batched in torch
and for one observation in numpy."""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from seqrank.agents.networks import mlp

LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0


class Actor(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int, hidden: int, layers: int):
        super().__init__()
        self.net = mlp(obs_dim, hidden, layers, 2 * act_dim)
        self.act_dim = act_dim

    def forward(
        self, obs: torch.Tensor, noise: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(sampled action, its log-probability (B, 1), deterministic action).

        `noise` is the standard normal draw (B, act_dim): the caller decides where it comes
        from, so two ways of running the same update can be fed the same numbers.
        """
        return squashed_gaussian(self.net(obs), noise)


def squashed_gaussian(
    head: torch.Tensor, noise: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """tanh(mean + std * noise), its log-probability and tanh(mean) from the actor's head."""
    mean, raw_log_std = head.chunk(2, dim=-1)
    log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (torch.tanh(raw_log_std) + 1)
    pre_tanh = mean + log_std.exp() * noise
    log_prob = (-0.5 * noise.pow(2) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1, True)
    # log|det d tanh(x)/dx| = 2 (log 2 - x - softplus(-2x)), numerically stable
    log_prob -= (2 * (math.log(2) - pre_tanh - F.softplus(-2 * pre_tanh))).sum(-1, True)
    return torch.tanh(pre_tanh), log_prob, torch.tanh(mean)


def act_one_numpy(
    net: nn.Sequential, obs: np.ndarray, noise: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(sampled action, deterministic action) of the squashed Gaussian for one observation,
    in numpy: the loop's action on a CPU, where torch's cost per call is most of the time
    at one row (31 against 129 us a step, AVX2). The formulas are `squashed_gaussian`'s,
    without the log-probability nobody reads when acting; the weights are read through
    views of the current parameters (fp32, on the host), so no copy goes stale."""
    x = np.asarray(obs, dtype=np.float32)
    for module in net:
        if isinstance(module, nn.Linear):
            x = module.weight.detach().numpy() @ x + module.bias.detach().numpy()
        else:  # the hidden layers' ReLU (`mlp`)
            x = np.maximum(x, 0.0, dtype=np.float32)
    mean, raw_log_std = np.split(x, 2)
    log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (np.tanh(raw_log_std) + 1)
    return np.tanh(mean + np.exp(log_std) * noise), np.tanh(mean)
