"""Implicit Q-Learning (Kostrikov, Nair and Levine, ICLR 2022): offline RL that never asks
the critic about an action outside the dataset.

One update, in the order of the authors' code (`ikostrikov/implicit_q_learning`,
`learner.py`):
    V    <- expectile regression of V(s) on min(Q1', Q2')(s, a), expectile tau
    pi   <- maximise mean(w * log pi(a|s)), w = min(exp(beta (min Q'(s, a) - V(s))), 100)
    Q    <- regression of Q1, Q2 on r + gamma (1 - terminal) V(s')
    Q'   <- (1 - 0.005) Q' + 0.005 Q
where Q' is the target critic and V is the value just updated. Every (s, a) is a dataset
row, so no value is read at an action the data never took.

The policy is the paper's MuJoCo one: a Gaussian whose mean is tanh of the network's output
and whose log-std is one learned vector (state-independent, clipped to [-5, 2]). The
weighted log-likelihood of dataset actions is then finite everywhere, actions of exactly
+-1 included, which a tanh-squashed distribution (SAC's) is not. Evaluation acts with the
mean. The actor's learning rate follows a cosine decay to 0 over the run's updates.

Observations are shifted and scaled inside the agent (the dataset's mean and std, as
LiRE's IQL does), so the policy acts on the environment's raw observations.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import torch
from torch import nn

from seqrank.agents.iql_settings import IQLSettings
from seqrank.agents.networks import mlp
from seqrank.agents.update_steps import descend, soft_update
from seqrank.buffer import Batch

LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0  # the authors' clip for the MuJoCo policy


def adam(params: Iterator[nn.Parameter], lr: float) -> torch.optim.Adam:
    """Adam with the fused kernel (torch >= 2.4 has it on the CPU and CUDA): one call per
    step for every parameter, where the default steps them one by one in Python on a CPU."""
    return torch.optim.Adam(params, lr=lr, fused=True)


def expectile_loss(diff: torch.Tensor, expectile: float) -> torch.Tensor:
    """|tau - 1(diff < 0)| diff^2 per row, diff = Q - V: under-estimates (diff > 0) weigh
    tau, over-estimates 1 - tau, so V settles at Q's tau-expectile (tau > 0.5: above the
    mean, towards the best action the data holds)."""
    weight = torch.where(diff > 0, expectile, 1 - expectile)
    return weight * diff.pow(2)


def q_target(
    reward: torch.Tensor, not_done: torch.Tensor, next_value: torch.Tensor, discount: float
) -> torch.Tensor:
    """r + gamma (1 - terminal) V(s'): a time limit is not terminal (`not_done` 1 there)."""
    return reward + discount * not_done * next_value


def advantage_weights(
    q: torch.Tensor, value: torch.Tensor, temperature: float, max_weight: float
) -> torch.Tensor:
    """exp(beta (Q - V)), clipped above at `max_weight` (one row cannot take the batch)."""
    return torch.exp(temperature * (q - value)).clamp(max=max_weight)


def cosine_rate(base: float, update: int, total: int) -> float:
    """The actor's rate at update `update` (from 0): base at 0, falling to 0 at `total`."""
    if total <= 0:
        return base
    return base * 0.5 * (1 + math.cos(math.pi * min(update, total) / total))


class GaussianPolicy(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int, hidden: int, layers: int):
        super().__init__()
        self.net = mlp(obs_dim, hidden, layers, act_dim)
        self.log_std = nn.Parameter(torch.zeros(act_dim))

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean in [-1, 1], log-std) of the action distribution."""
        log_std = self.log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)
        return torch.tanh(self.net(obs)), log_std

    def log_prob(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """log pi(action | obs) per row, (B, 1): a diagonal Gaussian's density."""
        mean, log_std = self(obs)
        z = (action - mean) / log_std.exp()
        return (-0.5 * z.pow(2) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1, keepdim=True)


class TwinQ(nn.Module):
    """Both critics as one ensemble of two MLPs, each layer's weights stacked (2, in, out):
    the first layer is one matmul for both (the input is shared), every later one a batched
    matmul, so an update runs a third of the critic's kernels it would as two networks.
    Initialised as two `mlp`s drawn one after the other (the same numbers as two separate
    networks from the same seed). `forward` gives both critics' values, (2, B, 1)."""

    MEMBERS = 2

    def __init__(self, obs_dim: int, act_dim: int, hidden: int, layers: int):
        super().__init__()
        nets = [mlp(obs_dim + act_dim, hidden, layers, 1) for _ in range(self.MEMBERS)]
        linears = [[m for m in net if isinstance(m, nn.Linear)] for net in nets]
        self.weights = nn.ParameterList(
            nn.Parameter(torch.stack([layer.weight.detach().t() for layer in column]))
            for column in zip(*linears, strict=True)
        )
        self.biases = nn.ParameterList(
            nn.Parameter(torch.stack([layer.bias.detach()[None] for layer in column]))
            for column in zip(*linears, strict=True)
        )

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        x = torch.cat([obs, action], -1)
        first, rest = self.weights[0], list(zip(self.weights, self.biases, strict=True))[1:]
        members, inputs, width = first.shape
        # the shared input times both members' first weights at once: (B, 2 * hidden)
        h = x @ first.permute(1, 0, 2).reshape(inputs, members * width)
        h = torch.relu(h.view(-1, members, width).transpose(0, 1) + self.biases[0])
        for i, (weight, bias) in enumerate(rest):
            h = torch.baddbmm(bias, h, weight)
            if i < len(rest) - 1:
                h = torch.relu(h)
        return h


class IQL:
    """Satisfies `agents.protocol.Policy` (act, state_dict, load_state_dict) and logs its
    last update's losses in `last_metrics`; offline, there is no replay to sample from and
    no critic reset, so the online `Agent`'s other calls are not offered."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        settings: IQLSettings,
        device: torch.device,
        obs_mean: np.ndarray | None = None,
        obs_std: np.ndarray | None = None,
    ):
        s = self.settings = settings
        self.device, self.act_dim = device, act_dim
        self.obs_mean = torch.zeros(obs_dim) if obs_mean is None else torch.as_tensor(obs_mean)
        self.obs_std = torch.ones(obs_dim) if obs_std is None else torch.as_tensor(obs_std)
        self.obs_mean = self.obs_mean.float().to(device)
        self.obs_std = self.obs_std.float().to(device)
        self.actor = GaussianPolicy(obs_dim, act_dim, s.hidden, s.layers).to(device)
        self.critic = TwinQ(obs_dim, act_dim, s.hidden, s.layers).to(device)
        self.critic_target = TwinQ(obs_dim, act_dim, s.hidden, s.layers).to(device)
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic_target.requires_grad_(False)
        self.value = mlp(obs_dim, s.hidden, s.layers, 1).to(device)
        self.actor_optimizer = adam(self.actor.parameters(), s.actor_lr)
        self.critic_optimizer = adam(self.critic.parameters(), s.critic_lr)
        self.value_optimizer = adam(self.value.parameters(), s.value_lr)
        self.updates = 0
        self._last: dict[str, torch.Tensor | float] = {}  # read as floats by `last_metrics`

    def normalize(self, obs: torch.Tensor) -> torch.Tensor:
        return (obs - self.obs_mean) / self.obs_std

    def update(self, batch: Batch) -> None:
        """One IQL update on a batch of dataset rows (raw observations)."""
        s = self.settings
        rows = len(batch.obs)
        # both observations normalised at once; obs and next_obs are views of the halves
        both = self.normalize(torch.cat([batch.obs, batch.next_obs]))
        obs = both[:rows]
        with torch.no_grad():
            target_q = self.critic_target(obs, batch.action).amin(0)
        value_loss = expectile_loss(target_q - self.value(obs), s.expectile).mean()
        descend(self.value_optimizer, value_loss)

        with torch.no_grad():  # the value just updated, as the authors' update reads it
            value, next_value = self.value(both).split(rows)
            weights = advantage_weights(target_q, value, s.temperature, s.max_weight)
        rate = cosine_rate(s.actor_lr, self.updates, s.decay_steps)
        for group in self.actor_optimizer.param_groups:
            group["lr"] = rate
        actor_loss = -(weights * self.actor.log_prob(obs, batch.action)).mean()
        descend(self.actor_optimizer, actor_loss)

        target = q_target(batch.reward, batch.not_done, next_value, s.discount)
        q = self.critic(obs, batch.action)  # (2, B, 1): both critics
        critic_loss = (q - target).pow(2).sum(0).mean()  # mean((Q1 - y)^2 + (Q2 - y)^2)
        descend(self.critic_optimizer, critic_loss)
        soft_update(self.critic_target.parameters(), self.critic.parameters(), s.target_rate)
        self.updates += 1
        self._last = {
            "value_loss": value_loss.detach(),
            "actor_loss": actor_loss.detach(),
            "critic_loss": critic_loss.detach(),
            "target_q": target_q,
            "value": value,
            "weights": weights,
            "actor_lr": rate,
        }

    @property
    def last_metrics(self) -> dict[str, float]:
        """The last update's losses and statistics, computed when read (a run logs them
        every `log_every` updates, not every update)."""
        if not self._last:
            return {}
        last, max_weight = self._last, self.settings.max_weight
        target_q, value, weights = last["target_q"], last["value"], last["weights"]
        assert isinstance(target_q, torch.Tensor) and isinstance(value, torch.Tensor)
        assert isinstance(weights, torch.Tensor)
        return {
            "value_loss": float(last["value_loss"]),
            "actor_loss": float(last["actor_loss"]),
            "critic_loss": float(last["critic_loss"]),
            "q_mean": float(target_q.mean()),
            "v_mean": float(value.mean()),
            "advantage_mean": float((target_q - value).mean()),
            "weight_mean": float(weights.mean()),
            "weight_clipped": float((weights >= max_weight).float().mean()),
            "actor_lr": float(last["actor_lr"]),
        }

    @torch.no_grad()
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> np.ndarray:
        """The mean action (`deterministic`), else one drawn from the policy and clipped to
        the action box; `generator` (on the CPU) draws the noise."""
        obs_t = torch.as_tensor(np.asarray(obs), dtype=torch.float32, device=self.device)
        mean, log_std = self.actor(self.normalize(obs_t.unsqueeze(0)))
        if deterministic:
            return mean[0].cpu().numpy()
        noise = torch.randn(self.act_dim, generator=generator).to(self.device)
        return (mean[0] + log_std.exp() * noise).clamp(-1, 1).cpu().numpy()

    def eval_metrics(self) -> dict[str, float]:
        return {
            "actor_lr": cosine_rate(self.settings.actor_lr, self.updates, self.settings.decay_steps)
        }

    def state_dict(self) -> dict[str, Any]:
        return {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "critic_target": self.critic_target.state_dict(),
            "value": self.value.state_dict(),
            "actor_optimizer": self.actor_optimizer.state_dict(),
            "critic_optimizer": self.critic_optimizer.state_dict(),
            "value_optimizer": self.value_optimizer.state_dict(),
            "obs_mean": self.obs_mean.cpu(),
            "obs_std": self.obs_std.cpu(),
            "updates": self.updates,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        if any(key.startswith("q1.") for key in state["critic"]):
            raise ValueError(
                "this checkpoint holds IQL's critics as two networks (seqrank before the "
                "twin critic became one ensemble); start the run again"
            )
        for name in ("actor", "critic", "critic_target", "value"):
            getattr(self, name).load_state_dict(state[name])
        for name in ("actor_optimizer", "critic_optimizer", "value_optimizer"):
            getattr(self, name).load_state_dict(state[name])
        self.obs_mean = state["obs_mean"].float().to(self.device)
        self.obs_std = state["obs_std"].float().to(self.device)
        self.updates = int(state["updates"])
