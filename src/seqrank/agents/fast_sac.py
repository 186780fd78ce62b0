"""The fast SAC path: the same update as `sac.SAC`, shaped for a GPU.

What differs from the reference, and why:
- The twin critics are one stack of weights (2, in, out), so each layer of both critics is
  one batched matmul.
- Nothing in an update reads a value back to the host: losses stay on the device until
  someone asks for them (`last_metrics`, every 1 000 steps in the trainer).
- Policy noise is drawn on the device (on the CPU it comes from the run's generator, so a
  resumed CPU run still reproduces an uninterrupted one).
- Adam is the fused implementation; on CUDA it is `capturable`, and the whole update
  (sampling from the device replay buffer included) is captured once in a CUDA graph and
  replayed, which removes the launch cost of its few hundred kernels.
- TF32 by default on CUDA, bf16 autocast as an option (`precision.py`).

Given the same weights, batch and noise, one fp32 update equals the reference's to float
rounding (tests/test_fast_path.py).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterable
from typing import Any

import torch
from torch import nn

from seqrank.agents.precision import autocast, matmul_precision
from seqrank.agents.sac import (
    Actor,
    SACSettings,
    TwinCritic,
    descend,
    host_noise,
    load_sac_state,
    sac_state,
    squashed_gaussian,
)
from seqrank.buffer import Batch, ReplayBuffer

WARMUP_UPDATES = 3  # eager runs on a side stream before capture, as CUDA graphs require


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
        """Orthogonal weights and zero biases per critic, like `sac.mlp`, in place."""
        for weight, bias in zip(self.weights, self.biases, strict=True):
            for member in weight:
                member.copy_(nn.init.orthogonal_(torch.empty(member.shape[::-1])).T)
            bias.zero_()

    @torch.no_grad()
    def copy_from(self, critic: TwinCritic) -> None:
        """Take the reference critic's weights (nn.Linear stores them transposed)."""
        for i, net in enumerate((critic.q1, critic.q2)):
            linears = [m for m in net if isinstance(m, nn.Linear)]
            for weight, bias, linear in zip(self.weights, self.biases, linears, strict=True):
                weight[i].copy_(linear.weight.T)
                bias[i, 0].copy_(linear.bias)

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


def _adam(params: Iterable[torch.Tensor], lr: float, device: torch.device) -> torch.optim.Adam:
    return torch.optim.Adam(params, lr=lr, fused=True, capturable=device.type == "cuda")


class FastSAC:
    """`sac.SAC`'s calls (`act`, `update`, `reset_critic`, `state_dict`, ...) plus
    `update_from_buffer`, the hot-loop update that samples on the device."""

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        settings: SACSettings,
        device: torch.device,
        precision: str = "fp32",
        graphs: bool | None = None,
    ):
        self.settings, self.device, self.precision = settings, device, precision
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.graphs = device.type == "cuda" if graphs is None else graphs
        h, n = settings.hidden, settings.layers
        self.actor = Actor(obs_dim, act_dim, h, n).to(device)
        self.critic = StackedTwinCritic(obs_dim, act_dim, h, n).to(device)
        self.critic_target = StackedTwinCritic(obs_dim, act_dim, h, n).to(device)
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic_target.requires_grad_(False)
        self.log_alpha = torch.tensor(
            math.log(settings.init_temperature), device=device, requires_grad=True
        )
        self.target_entropy = -float(act_dim)
        self.actor_opt = _adam(self.actor.parameters(), settings.actor_lr, device)
        self.critic_opt = _adam(self.critic.parameters(), settings.critic_lr, device)
        self.alpha_opt = _adam([self.log_alpha], settings.alpha_lr, device)
        self.updates = 0
        self._metrics: dict[str, torch.Tensor] = {}
        self._graph: torch.cuda.CUDAGraph | None = None
        self._target_graph: torch.cuda.CUDAGraph | None = None
        self._graph_key: tuple[int, int] | None = None
        self.capture_seconds = 0.0

    # ---- the calls SAC offers -------------------------------------------------------
    @property
    def alpha(self) -> torch.Tensor:
        return self.log_alpha.exp()

    @property
    def last_metrics(self) -> dict[str, float]:
        """The last update's losses, read back now (the only host sync they cost)."""
        return {name: float(value) for name, value in self._metrics.items()}

    def eval_metrics(self) -> dict[str, float]:
        return {"alpha": float(self.alpha.detach())}

    def noise(self, rows: int, generator: torch.Generator) -> torch.Tensor:
        if self.device.type == "cpu":
            return host_noise(rows, self.act_dim, generator, self.device)
        return torch.randn((rows, self.act_dim), device=self.device)

    @torch.no_grad()
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> Any:
        obs_t = torch.as_tensor(obs, dtype=torch.float32).to(self.device).unsqueeze(0)
        with matmul_precision(self.precision):
            sampled, _, mean = self._policy(obs_t, self.noise(1, generator))
        return (mean if deterministic else sampled)[0].cpu().numpy()

    def critic_target_value(self, batch: Batch, generator: torch.Generator) -> torch.Tensor:
        """gamma * not_done * (min target Q(s', a') - alpha log pi(a'|s')), no gradient."""
        return self._target_value(batch, self.noise(len(batch.obs), generator))

    def reset_critic(self) -> None:
        """Fresh critic weights, target and Adam state, written in place so that a captured
        graph stays valid; actor and temperature are kept."""
        self.critic.reinitialise()
        self.critic_target.load_state_dict(self.critic.state_dict())
        _zero_optimizer_state(self.critic_opt)

    def update(self, batch: Batch, generator: torch.Generator) -> dict[str, float]:
        """An eager update from a given batch (pre-training, MRN, after the critic reset).
        Returns nothing read back: metrics are in `last_metrics`."""
        rows = len(batch.obs)
        next_noise = self.noise(rows, generator)
        return self.update_with_noise(batch, next_noise, self.noise(rows, generator))

    def update_with_noise(
        self, batch: Batch, next_noise: torch.Tensor, noise: torch.Tensor
    ) -> dict[str, float]:
        with matmul_precision(self.precision):
            self._step(batch, next_noise, noise)
            self._count_update(self._soft_update_target)
        return {}

    def update_from_buffer(
        self, buffer: ReplayBuffer, batch_size: int, generator: torch.Generator
    ) -> None:
        """The hot-loop update: on CUDA a replay of the captured graph, else eager."""
        if not self.graphs or not self.actor_opt.state:
            # eager; also the very first update, which creates the optimisers' state
            self.update(buffer.sample(batch_size, generator), generator)
            return
        if self._graph_key != (id(buffer), batch_size):
            self._capture(buffer, batch_size)
        assert self._graph is not None and self._target_graph is not None
        self._graph.replay()
        self._count_update(self._target_graph.replay)

    # ---- the update -----------------------------------------------------------------
    def _count_update(self, target_update: Callable[[], None]) -> None:
        self.updates += 1
        if self.updates % self.settings.target_update_every == 0:
            target_update()

    def _policy(
        self, obs: torch.Tensor, noise: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The actor's network in the chosen precision, the squashing always in fp32."""
        with autocast(self.precision, self.device):
            head = self.actor.net(obs)
        return squashed_gaussian(head.float(), noise)

    def _q(self, critic: StackedTwinCritic, obs: torch.Tensor, action: torch.Tensor) -> Any:
        with autocast(self.precision, self.device):
            return critic.stacked(obs, action).float()

    def _target_value(self, batch: Batch, noise: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            next_action, next_log_prob, _ = self._policy(batch.next_obs, noise)
            q = self._q(self.critic_target, batch.next_obs, next_action)
            soft_value = torch.min(q[0], q[1]) - self.alpha * next_log_prob
            return self.settings.discount * batch.not_done * soft_value

    def _step(self, batch: Batch, next_noise: torch.Tensor, noise: torch.Tensor) -> None:
        """Critic, then actor and temperature, as `SAC.update_with_noise`, no host reads."""
        target = batch.reward + self._target_value(batch, next_noise)
        q = self._q(self.critic, batch.obs, batch.action)
        # the mean over the batch for each critic, summed: mse(q1) + mse(q2)
        critic_loss = (q - target).pow(2).mean(dim=(1, 2)).sum()
        descend(self.critic_opt, critic_loss)

        self.critic.requires_grad_(False)  # the actor's loss needs no critic gradients
        action, log_prob, _ = self._policy(batch.obs, noise)
        q_pi = self._q(self.critic, batch.obs, action)
        self.critic.requires_grad_(True)
        actor_loss = (self.alpha.detach() * log_prob - torch.min(q_pi[0], q_pi[1])).mean()
        descend(self.actor_opt, actor_loss)

        alpha_loss = (self.alpha * (-log_prob.detach() - self.target_entropy)).mean()
        descend(self.alpha_opt, alpha_loss)
        self._write_metrics(critic_loss, actor_loss)

    def _write_metrics(self, critic_loss: torch.Tensor, actor_loss: torch.Tensor) -> None:
        values = {
            "critic_loss": critic_loss.detach(),
            "actor_loss": actor_loss.detach(),
            "alpha": self.alpha.detach(),
        }
        if not self._metrics:
            self._metrics = {name: value.clone() for name, value in values.items()}
            return
        for name, value in values.items():  # in place: graph replays write here too
            self._metrics[name].copy_(value)

    @torch.no_grad()
    def _soft_update_target(self) -> None:
        targets: list[torch.Tensor] = list(self.critic_target.parameters())
        sources: list[torch.Tensor] = list(self.critic.parameters())
        torch._foreach_lerp_(targets, sources, self.settings.tau)

    # ---- CUDA graphs ----------------------------------------------------------------
    def _sampled_step(self, buffer: ReplayBuffer, batch_size: int) -> None:
        batch = buffer.sample_on_device(batch_size)
        self._step(batch, self.noise(batch_size, _UNUSED), self.noise(batch_size, _UNUSED))

    def _capture(self, buffer: ReplayBuffer, batch_size: int) -> None:
        """Warm up on a side stream, restore the state the warm-up changed, capture."""
        if buffer.storage != self.device:
            raise ValueError("graph updates need the replay buffer on the training device")
        started = time.perf_counter()  # reported apart from the update time
        if not self._metrics:  # the metric tensors must exist before capture
            zero = torch.zeros((), device=self.device)
            self._write_metrics(zero, zero)
        saved = self._snapshot()
        side = torch.cuda.Stream()
        side.wait_stream(torch.cuda.current_stream())
        with torch.cuda.stream(side), matmul_precision(self.precision):
            for _ in range(WARMUP_UPDATES):
                self._sampled_step(buffer, batch_size)
        torch.cuda.current_stream().wait_stream(side)
        self._restore(saved)
        graph, target_graph = torch.cuda.CUDAGraph(), torch.cuda.CUDAGraph()
        with matmul_precision(self.precision):
            with torch.cuda.graph(graph):
                self._sampled_step(buffer, batch_size)
            with torch.cuda.graph(target_graph):
                self._soft_update_target()
        torch.cuda.synchronize()
        self._graph, self._target_graph = graph, target_graph
        self._graph_key = (id(buffer), batch_size)
        self.capture_seconds += time.perf_counter() - started

    def _tensors(self) -> list[torch.Tensor]:
        """Every tensor an update changes: weights, temperature, optimiser state."""
        tensors = [*self.actor.parameters(), *self.critic.parameters(), self.log_alpha]
        tensors += list(self.critic_target.parameters())
        for opt in (self.actor_opt, self.critic_opt, self.alpha_opt):
            for state in opt.state.values():
                tensors += [v for v in state.values() if isinstance(v, torch.Tensor)]
        return tensors

    def _snapshot(self) -> list[tuple[torch.Tensor, torch.Tensor]]:
        # the optimisers' state must exist (it does after one step) before it can be saved
        if not self.actor_opt.state:
            raise RuntimeError("capture before the first update: run one eager update first")
        return [(t, t.detach().clone()) for t in self._tensors()]

    @staticmethod
    @torch.no_grad()
    def _restore(saved: list[tuple[torch.Tensor, torch.Tensor]]) -> None:
        for tensor, copy in saved:
            tensor.copy_(copy)

    # ---- checkpoints ----------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        return sac_state(self)

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Weights are copied in place; the optimisers' state is replaced, so a captured
        graph is dropped and captured again on the next update."""
        load_sac_state(self, state)
        self._graph = self._target_graph = None
        self._graph_key = None


_UNUSED = torch.Generator()  # the device draws its own noise on CUDA


@torch.no_grad()
def _zero_optimizer_state(optimizer: torch.optim.Optimizer) -> None:
    """A fresh optimiser's state, written into the existing tensors."""
    for state in optimizer.state.values():
        for value in state.values():
            if isinstance(value, torch.Tensor):
                value.zero_()
