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

    def forward(
        self, obs: torch.Tensor, generator: torch.Generator | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(sampled action, its log-probability (B, 1), deterministic action)."""
        mean, raw_log_std = self.net(obs).chunk(2, dim=-1)
        log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (torch.tanh(raw_log_std) + 1)
        std = log_std.exp()
        noise = torch.randn(mean.shape, generator=generator, device="cpu").to(mean.device)
        pre_tanh = mean + std * noise
        log_prob = (-0.5 * noise.pow(2) - log_std - 0.5 * math.log(2 * math.pi)).sum(-1, True)
        # log|det d tanh(x)/dx| = 2 (log 2 - x - softplus(-2x)), numerically stable
        log_prob -= (2 * (math.log(2) - pre_tanh - F.softplus(-2 * pre_tanh))).sum(-1, True)
        return torch.tanh(pre_tanh), log_prob, torch.tanh(mean)


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

    @torch.no_grad()
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> Any:
        obs_t = torch.as_tensor(obs, dtype=torch.float32, device=self.device).unsqueeze(0)
        sampled, _, mean = self.actor(obs_t, generator)
        return (mean if deterministic else sampled)[0].cpu().numpy()

    def critic_target_value(self, batch: Batch, generator: torch.Generator) -> torch.Tensor:
        """gamma * not_done * (min target Q(s', a') - alpha log pi(a'|s')), no gradient."""
        with torch.no_grad():
            next_action, next_log_prob, _ = self.actor(batch.next_obs, generator)
            q1, q2 = self.critic_target(batch.next_obs, next_action)
            soft_value = torch.min(q1, q2) - self.alpha * next_log_prob
            return self.settings.discount * batch.not_done * soft_value

    def update_critic(self, batch: Batch, generator: torch.Generator) -> float:
        target = batch.reward + self.critic_target_value(batch, generator)
        q1, q2 = self.critic(batch.obs, batch.action)
        loss = F.mse_loss(q1, target) + F.mse_loss(q2, target)
        self.critic_opt.zero_grad(set_to_none=True)
        loss.backward()
        self.critic_opt.step()
        return float(loss.detach())

    def update_actor_and_alpha(self, batch: Batch, generator: torch.Generator) -> dict[str, float]:
        action, log_prob, _ = self.actor(batch.obs, generator)
        q1, q2 = self.critic(batch.obs, action)
        actor_loss = (self.alpha.detach() * log_prob - torch.min(q1, q2)).mean()
        self.actor_opt.zero_grad(set_to_none=True)
        actor_loss.backward()
        self.actor_opt.step()
        alpha_loss = (self.alpha * (-log_prob.detach() - self.target_entropy)).mean()
        self.alpha_opt.zero_grad(set_to_none=True)
        alpha_loss.backward()
        self.alpha_opt.step()
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
        metrics = {"critic_loss": self.update_critic(batch, generator)}
        metrics.update(self.update_actor_and_alpha(batch, generator))
        self.updates += 1
        if self.updates % self.settings.target_update_every == 0:
            self.soft_update_target()
        self.last_metrics = metrics
        return metrics

    def state_dict(self) -> dict[str, Any]:
        return {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "critic_target": self.critic_target.state_dict(),
            "log_alpha": self.log_alpha.detach(),
            "actor_opt": self.actor_opt.state_dict(),
            "critic_opt": self.critic_opt.state_dict(),
            "alpha_opt": self.alpha_opt.state_dict(),
            "updates": self.updates,
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self.actor.load_state_dict(state["actor"])
        self.critic.load_state_dict(state["critic"])
        self.critic_target.load_state_dict(state["critic_target"])
        with torch.no_grad():
            self.log_alpha.copy_(state["log_alpha"])
        self.actor_opt.load_state_dict(state["actor_opt"])
        self.critic_opt.load_state_dict(state["critic_opt"])
        self.alpha_opt.load_state_dict(state["alpha_opt"])
        self.updates = state["updates"]
