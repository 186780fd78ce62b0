"""Soft actor-critic as SPEC section 2 states it (PEBBLE's settings).

The reference path and the fast path on CUDA are this one autograd update run two ways
(`Execution`): the fast path
stacks the twin critics into batched matmuls, uses fused Adam, draws policy noise on the
device and, on CUDA, replays the update from a captured graph (`cuda_graph.GraphedCall`);
precision (fp32, TF32, bf16 autocast) is a context around the same code. On a CPU the fast
path's update is `flat_update`: the same arithmetic written out over flat buffers (fewer
operations; bf16 by explicit casts rather than autocast), whose parameters are views of
those buffers (checked after every load and critic reset). Nothing in an update reads a
value back to the host: losses are read when `last_metrics` is asked for.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterable
from dataclasses import replace
from typing import Any

import torch
import torch.nn.functional as F

from seqrank.agents.sac.critics import Critic, StackedTwinCritic, TwinCritic
from seqrank.agents.sac.cuda_graph import GraphedCall
from seqrank.agents.sac.flat_update import FlatSACUpdate
from seqrank.agents.sac.graph_check import UpdateProbe, check_first_replay
from seqrank.agents.sac.networks import Actor, act_one_numpy, squashed_gaussian
from seqrank.agents.sac.precision import autocast, matmul_precision
from seqrank.agents.sac.settings import Execution, SACSettings
from seqrank.agents.sac.state import load_sac_state, sac_state
from seqrank.agents.update_steps import descend, soft_update
from seqrank.buffer import Batch, BatchSource


def critic_loss(q: tuple[torch.Tensor, torch.Tensor], target: torch.Tensor) -> torch.Tensor:
    """Both critics' mean squared error against one target, summed."""
    return F.mse_loss(q[0], target) + F.mse_loss(q[1], target)


class SAC:
    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        settings: SACSettings,
        device: torch.device,
        execution: Execution | None = None,
    ):
        self.settings, self.device = settings, device
        self.execution = execution if execution is not None else Execution()
        self.obs_dim, self.act_dim = obs_dim, act_dim
        h, n = settings.hidden, settings.layers
        if self.execution.flat and (device.type != "cpu" or not self.execution.stacked_critics):
            raise ValueError("the flat update runs on a CPU with stacked critics only")
        self.actor = Actor(obs_dim, act_dim, h, n).to(device)
        layout = StackedTwinCritic if self.execution.stacked_critics else TwinCritic
        self.critic: Critic = layout(obs_dim, act_dim, h, n).to(device)
        self.critic_target: Critic = layout(obs_dim, act_dim, h, n).to(device)
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic_target.requires_grad_(False)
        self.log_alpha = torch.tensor(
            math.log(settings.init_temperature), device=device, requires_grad=True
        )
        self.target_entropy = -float(act_dim)
        self.actor_opt = self._adam(self.actor.parameters(), settings.actor_lr)
        self.critic_opt = self._adam(self.critic.parameters(), settings.critic_lr)
        self.alpha_opt = self._adam([self.log_alpha], settings.alpha_lr)
        self.updates = 0
        self._metrics: dict[str, torch.Tensor] = {}
        self._graphs: tuple[tuple[int, int], GraphedCall, GraphedCall] | None = None
        self._graph_inputs: tuple[Batch, torch.Tensor, torch.Tensor] | None = None
        self.graph_checked = False
        self.fallback: str | None = None  # why the graph updates were given up, if they were
        self._flat = FlatSACUpdate(self) if self.execution.flat else None

    def _adam(self, params: Iterable[torch.Tensor], lr: float) -> torch.optim.Adam:
        if not self.execution.fused_adam:
            return torch.optim.Adam(params, lr=lr)
        capturable = self.device.type == "cuda"
        return torch.optim.Adam(params, lr=lr, fused=True, capturable=capturable)

    # ---- what the training loop calls (the Agent protocol) ----------------------------
    @property
    def precision(self) -> str:
        return self.execution.precision

    @property
    def discount(self) -> float:
        return self.settings.discount

    @property
    def alpha(self) -> torch.Tensor:
        return self.log_alpha.exp()

    @property
    def last_metrics(self) -> dict[str, float]:
        """The last update's losses, read back now (the only host sync they cost)."""
        return {name: float(value) for name, value in self._metrics.items()}

    def eval_metrics(self) -> dict[str, float]:
        return {"alpha": float(self.alpha.detach())}

    @torch.no_grad()
    def act(self, obs: Any, deterministic: bool, generator: torch.Generator) -> Any:
        noise = self.noise(1, generator)
        if self.device.type == "cpu":
            # one observation on a CPU: the actor in its weights' own fp32 and in numpy,
            # on every path; bf16 pays off only in batches (a step's action took 396 us in
            # bf16 against 191 us in torch's fp32 on the flat path's machine)
            drawn, mean = act_one_numpy(self.actor.net, obs, noise[0].numpy())
            return mean if deterministic else drawn
        obs_t = torch.as_tensor(obs, dtype=torch.float32).to(self.device).unsqueeze(0)
        with matmul_precision(self.execution.precision):
            sampled, _, mean_t = self._policy(obs_t, noise)
        return (mean_t if deterministic else sampled)[0].cpu().numpy()

    def update(self, batch: Batch, generator: torch.Generator) -> None:
        """One update from a given batch: critic, actor and temperature, and every
        `target_update_every` updates the target critic."""
        rows = len(batch.obs)
        next_noise = self.noise(rows, generator)
        self.update_with_noise(batch, next_noise, self.noise(rows, generator))

    def update_from(self, replay: BatchSource, batch_size: int, generator: torch.Generator) -> None:
        """The hot-loop update: a batch from `replay`; replayed from a graph on CUDA."""
        if not self.execution.graphs or not self.actor_opt.state:
            # eager; also the very first update, which creates the optimisers' state
            self.update(replay.sample(batch_size, generator), generator)
            return
        step, target = self._captured(replay, batch_size)
        with matmul_precision(self.execution.precision):
            if self.graph_checked:
                step()
            elif not self._checked_first_replay(step):  # the capture raised: no update yet
                self.update(replay.sample(batch_size, generator), generator)
                return
        self._count_update(target if self.fallback is None else self._soft_update_target)

    def _checked_first_replay(self, step: GraphedCall) -> bool:
        """The first replay checked against the eager update on its batch (`graph_check`);
        on a failure the run continues eager, saying so once. Whether an update was made."""
        self.graph_checked = True

        def eager() -> None:
            assert self._graph_inputs is not None  # the capture recorded them
            self._step(*self._graph_inputs)

        weights = [*self.actor.parameters(), *self.critic.parameters(), self.log_alpha]
        probe = UpdateProbe(step, eager, self._touched, lambda: weights, lambda: self.last_metrics)
        failure, updated = check_first_replay(probe)
        if failure is not None:
            self.fallback = failure
            self.execution, self._graphs = replace(self.execution, graphs=False), None
            sys.stderr.write(
                f"warning: fast path: {failure}; the run continues with eager updates "
                "(--path reference runs without the fast path)\n"
            )
        return updated

    def reset_critic(self) -> None:
        """Fresh critic weights, target and Adam state, written in place so that a captured
        graph stays valid; actor and temperature are kept."""
        self.critic.reinitialise()
        self.critic_target.reinitialise()
        self.critic_target.load_state_dict(self.critic.state_dict())
        _zero_optimizer_state(self.critic_opt)
        if self._flat is not None:
            self._flat.check_views()

    def state_dict(self) -> dict[str, Any]:
        return sac_state(self)

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Weights and optimiser state are copied into the existing tensors, so a captured
        graph stays valid."""
        load_sac_state(self, state)
        if self._flat is not None:
            self._flat.check_views()
            self._flat.adopt_optimiser_state()

    # ---- the update ---------------------------------------------------------------------
    def noise(self, rows: int, generator: torch.Generator) -> torch.Tensor:
        """Standard normal policy noise: from the run's generator on the host (a resumed
        run then reproduces an uninterrupted one), or drawn on the device (fast, CUDA)."""
        if self.execution.device_noise:
            return torch.randn((rows, self.act_dim), device=self.device)
        return torch.randn((rows, self.act_dim), generator=generator).to(self.device)

    def critic_target_value(self, batch: Batch, generator: torch.Generator) -> torch.Tensor:
        """gamma * not_done * (min target Q(s', a') - alpha log pi(a'|s')), no gradient."""
        return self._target_value(batch, self.noise(len(batch.obs), generator))

    def update_with_noise(
        self, batch: Batch, next_noise: torch.Tensor, noise: torch.Tensor
    ) -> None:
        """The update for given policy noise: for s' (critic target), then for s (actor)."""
        with matmul_precision(self.execution.precision):
            self._step(batch, next_noise, noise)
            self._count_update(self._soft_update_target)

    def _count_update(self, target_update: Any) -> None:
        self.updates += 1
        if self.updates % self.settings.target_update_every == 0:
            target_update()

    def _policy(
        self, obs: torch.Tensor, noise: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The actor's network in the chosen precision, the squashing always in fp32."""
        with autocast(self.execution.precision, self.device):
            head = self.actor.net(obs)
        return squashed_gaussian(head.float(), noise)

    def _q(
        self, critic: Critic, obs: torch.Tensor, action: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        with autocast(self.execution.precision, self.device):
            q1, q2 = critic(obs, action)
        return q1.float(), q2.float()

    def _target_value(self, batch: Batch, noise: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            next_action, next_log_prob, _ = self._policy(batch.next_obs, noise)
            q1, q2 = self._q(self.critic_target, batch.next_obs, next_action)
            soft_value = torch.min(q1, q2) - self.alpha * next_log_prob
            return self.settings.discount * batch.not_done * soft_value

    def _step(self, batch: Batch, next_noise: torch.Tensor, noise: torch.Tensor) -> None:
        if self._flat is not None:
            self._write_metrics(*self._flat.step(batch, next_noise, noise))
            return
        target = batch.reward + self._target_value(batch, next_noise)
        loss = critic_loss(self._q(self.critic, batch.obs, batch.action), target)
        descend(self.critic_opt, loss)

        self.critic.requires_grad_(False)  # the actor's loss needs no critic gradients
        action, log_prob, _ = self._policy(batch.obs, noise)
        q1_pi, q2_pi = self._q(self.critic, batch.obs, action)
        self.critic.requires_grad_(True)
        actor_loss = (self.alpha.detach() * log_prob - torch.min(q1_pi, q2_pi)).mean()
        descend(self.actor_opt, actor_loss)

        alpha_loss = (self.alpha * (-log_prob.detach() - self.target_entropy)).mean()
        descend(self.alpha_opt, alpha_loss)
        self._write_metrics(loss, actor_loss)

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

    def _soft_update_target(self) -> None:
        if self._flat is not None:
            self._flat.soft_update(self.settings.tau)
            return
        soft_update(self.critic_target.parameters(), self.critic.parameters(), self.settings.tau)

    # ---- CUDA graphs --------------------------------------------------------------------
    def _captured(self, replay: BatchSource, batch_size: int) -> tuple[GraphedCall, GraphedCall]:
        key = (id(replay), batch_size)
        if self._graphs is None or self._graphs[0] != key:
            if replay.storage != self.device:
                raise ValueError("graph updates need the replay buffer on the training device")

            def sampled_step() -> None:
                batch = replay.sample_on_device(batch_size)
                noises = self.noise(batch_size, _UNUSED), self.noise(batch_size, _UNUSED)
                self._graph_inputs = (batch, *noises)  # the check replays these eagerly
                self._step(batch, *noises)

            step = GraphedCall(sampled_step, self._touched)
            self._graphs = (key, step, GraphedCall(self._soft_update_target, list, warmup=False))
        return self._graphs[1], self._graphs[2]

    @property
    def capture_seconds(self) -> float:
        """Time spent capturing graphs (reported apart from the update time)."""
        return 0.0 if self._graphs is None else sum(g.capture_seconds for g in self._graphs[1:])

    def _touched(self) -> list[torch.Tensor]:
        """Every tensor an update changes: weights, temperature, optimiser state, metrics."""
        tensors = [*self.actor.parameters(), *self.critic.parameters(), self.log_alpha]
        tensors += [*self.critic_target.parameters(), *self._metrics.values()]
        for opt in (self.actor_opt, self.critic_opt, self.alpha_opt):
            for state in opt.state.values():
                tensors += [v for v in state.values() if isinstance(v, torch.Tensor)]
        return tensors


_UNUSED = torch.Generator()  # the device draws its own noise on CUDA


@torch.no_grad()
def _zero_optimizer_state(optimizer: torch.optim.Optimizer) -> None:
    """A fresh optimiser's state, written into the existing tensors."""
    for state in optimizer.state.values():
        for value in state.values():
            if isinstance(value, torch.Tensor):
                value.zero_()
