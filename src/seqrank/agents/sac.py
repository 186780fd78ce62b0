"""Soft actor-critic as SPEC section 2 states it (PEBBLE's settings)."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from seqrank.buffer import Batch

LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0


def mlp(inputs: int, hidden: int, layers: int, outputs: int) -> nn.Sequential:
    """`layers` hidden ReLU layers; orthogonal weights, zero biases."""
    sizes = [inputs] + [hidden] * layers
    modules: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes):
        modules += [nn.Linear(a, b), nn.ReLU()]
    modules.append(nn.Linear(sizes[-1], outputs))
    for module in modules:
        if isinstance(module, nn.Linear):
            nn.init.orthogonal_(module.weight)
            nn.init.zeros_(module.bias)
    return nn.Sequential(*modules)


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
        from, so the reference and fast paths can be fed the same numbers.
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


def descend(optimizer: torch.optim.Optimizer, loss: torch.Tensor) -> None:
    """One optimiser step on `loss`."""
    optimizer.zero_grad(set_to_none=True)
    loss.backward()
    optimizer.step()


def host_noise(rows: int, act_dim: int, generator: torch.Generator, device: torch.device) -> Any:
    """Standard normal noise drawn on the host from the run's generator (the reference way)."""
    return torch.randn((rows, act_dim), generator=generator).to(device)


class TwinCritic(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int, hidden: int, layers: int):
        super().__init__()
        self.q1 = mlp(obs_dim + act_dim, hidden, layers, 1)
        self.q2 = mlp(obs_dim + act_dim, hidden, layers, 1)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([obs, action], dim=-1)
        return self.q1(x), self.q2(x)


@dataclass(frozen=True)
class SACSettings:
    hidden: int
    layers: int
    actor_lr: float
    critic_lr: float
    alpha_lr: float
    init_temperature: float
    discount: float
    tau: float
    target_update_every: int


class SAC:
    def __init__(self, obs_dim: int, act_dim: int, settings: SACSettings, device: torch.device):
        self.settings, self.device = settings, device
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.actor = Actor(obs_dim, act_dim, settings.hidden, settings.layers).to(device)
        self.log_alpha = torch.tensor(
            math.log(settings.init_temperature), device=device, requires_grad=True
        )
        self.target_entropy = -float(act_dim)
        self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=settings.actor_lr)
        self.alpha_opt = torch.optim.Adam([self.log_alpha], lr=settings.alpha_lr)
        self.updates = 0
        self.last_metrics: dict[str, float] = {}
        self.reset_critic()

    def reset_critic(self) -> None:
        """Fresh critic, target and critic optimiser; actor and temperature are kept."""
        s = self.settings
        self.critic = TwinCritic(self.obs_dim, self.act_dim, s.hidden, s.layers).to(self.device)
        self.critic_target = TwinCritic(self.obs_dim, self.act_dim, s.hidden, s.layers).to(
            self.device
        )
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=s.critic_lr)

    @property
    def alpha(self) -> torch.Tensor:
        return self.log_alpha.exp()

    def eval_metrics(self) -> dict[str, float]:
        return {"alpha": float(self.alpha.detach())}

    def noise(self, rows: int, generator: torch.Generator) -> torch.Tensor:
        return host_noise(rows, self.act_dim, generator, self.device)

    @torch.no_grad()
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> Any:
        obs_t = torch.as_tensor(obs, dtype=torch.float32, device=self.device).unsqueeze(0)
        sampled, _, mean = self.actor(obs_t, self.noise(1, generator))
        return (mean if deterministic else sampled)[0].cpu().numpy()

    def critic_target_value(self, batch: Batch, generator: torch.Generator) -> torch.Tensor:
        """gamma * not_done * (min target Q(s', a') - alpha log pi(a'|s')), no gradient."""
        return self.target_value_with(batch, self.noise(len(batch.obs), generator))

    def target_value_with(self, batch: Batch, noise: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            next_action, next_log_prob, _ = self.actor(batch.next_obs, noise)
            q1, q2 = self.critic_target(batch.next_obs, next_action)
            soft_value = torch.min(q1, q2) - self.alpha * next_log_prob
            return self.settings.discount * batch.not_done * soft_value

    def update_critic(self, batch: Batch, noise: torch.Tensor) -> float:
        target = batch.reward + self.target_value_with(batch, noise)
        q1, q2 = self.critic(batch.obs, batch.action)
        loss = F.mse_loss(q1, target) + F.mse_loss(q2, target)
        descend(self.critic_opt, loss)
        return float(loss.detach())

    def update_actor_and_alpha(self, batch: Batch, noise: torch.Tensor) -> dict[str, float]:
        action, log_prob, _ = self.actor(batch.obs, noise)
        q1, q2 = self.critic(batch.obs, action)
        actor_loss = (self.alpha.detach() * log_prob - torch.min(q1, q2)).mean()
        descend(self.actor_opt, actor_loss)
        alpha_loss = (self.alpha * (-log_prob.detach() - self.target_entropy)).mean()
        descend(self.alpha_opt, alpha_loss)
        return {"actor_loss": float(actor_loss.detach()), "alpha": float(self.alpha.detach())}

    def soft_update_target(self) -> None:
        with torch.no_grad():
            tau = self.settings.tau
            for p, tp in zip(
                self.critic.parameters(), self.critic_target.parameters(), strict=True
            ):
                tp.lerp_(p, tau)

    def update(self, batch: Batch, generator: torch.Generator) -> dict[str, float]:
        """One SAC step: critic, actor and temperature, and every 2nd step the target."""
        rows = len(batch.obs)
        next_noise = self.noise(rows, generator)
        noise = self.noise(rows, generator)
        return self.update_with_noise(batch, next_noise, noise)

    def update_with_noise(
        self, batch: Batch, next_noise: torch.Tensor, noise: torch.Tensor
    ) -> dict[str, float]:
        """The update for given policy noise: for s' (critic target), then for s (actor)."""
        metrics = {"critic_loss": self.update_critic(batch, next_noise)}
        metrics.update(self.update_actor_and_alpha(batch, noise))
        self.updates += 1
        if self.updates % self.settings.target_update_every == 0:
            self.soft_update_target()
        self.last_metrics = metrics
        return metrics

    def state_dict(self) -> dict[str, Any]:
        return sac_state(self)

    def load_state_dict(self, state: dict[str, Any]) -> None:
        load_sac_state(self, state)


def sac_state(agent: Any) -> dict[str, Any]:
    """Weights, temperature, optimisers and update count of a SAC agent (either path)."""
    state = {name: getattr(agent, name).state_dict() for name in SAC_PARTS}
    return {**state, "log_alpha": agent.log_alpha.detach().clone(), "updates": agent.updates}


def load_sac_state(agent: Any, state: dict[str, Any]) -> None:
    """The inverse of `sac_state`; weights are copied into the existing tensors."""
    for name in SAC_PARTS:
        getattr(agent, name).load_state_dict(state[name])
    with torch.no_grad():
        agent.log_alpha.copy_(state["log_alpha"])
    agent.updates = state["updates"]


SAC_PARTS = ("actor", "critic", "critic_target", "actor_opt", "critic_opt", "alpha_opt")
