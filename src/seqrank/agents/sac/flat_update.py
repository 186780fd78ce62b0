"""The fast path's SAC update on a CPU: the same arithmetic as autograd's, with fewer operations.

On a CPU the update's cost beyond its matrix products is per operation (autograd's
bookkeeping, a cast per weight per use under autocast, an optimiser call per tensor), not
arithmetic. So here each network's weights, gradients and Adam moments live in one flat
buffer (`flat_buffers`): one cast gives a network's weights in the compute precision, one
fused Adam call steps it, one lerp moves the target critic. The backward passes are
written by hand (`flat_backward`: two ReLU MLPs and the squashed Gaussian's head) and the
actor runs once on the next and current observations together (its weights do not change
before its own step). `tests/agents/test_flat_update.py` holds it to autograd's update;
`tests/agents/test_sac_by_hand.py` holds both to numbers worked out by hand.

The update, for a batch of B rows (SPEC section 1; autograd's `SAC._step` computes the same):

    y      = r + gamma * not_done * (min(Q1', Q2')(s', a') - alpha log pi(a'|s'))
    L_Q    = sum_k mean (Q_k(s, a) - y)^2           dL_Q/dQ_k = 2 (Q_k - y) / B
    L_pi   = mean (alpha log pi(a~|s) - min(Q1, Q2)(s, a~))
             dL_pi/dQ_k = -1/B where Q_k is the smaller (1/2 each on a tie: `min_gradient`),
             dL_pi/dlog pi = alpha / B, dL_pi/da~ through the stepped critic's input
             gradient (its last act_dim columns; no gradient for the critic's weights)
    L_alpha = mean alpha (-log pi(a~|s) - H_target)  dL/dlog alpha = alpha mean(-log pi - H_target)
    target <- (1 - tau) target + tau critic, every `target_update_every` updates

Invariants (what a change here must keep):

- The modules' parameters are views of the flat buffers. Whatever gives a parameter other
  storage (assigning `param.data`, a new `nn.Parameter`: the list in `flat_buffers`)
  unhooks its module from the update without an error; `FlatSACUpdate.check_views` raises
  instead, and `SAC` runs it after every load and critic reset.
- `param.grad` is always None: the gradients live in the flat gradient buffers
  (`FlatAdam.grad`). Gradient clipping or grad-norm logging must read or scale those
  (`critic_adam.grad`, `actor_adam.grad`) before the Adam step, not `param.grad`.
- The `torch.optim.Adam` objects stay as the record of Adam's state (checkpoints read
  them): their per-parameter moments are views of the flat moments, and they are never
  stepped here (stepping one raises).

When to delete it: this module exists only because eager autograd is slower on a CPU. Once
`torch.compile` of the autograd update is at least as fast as this update in fp32 and bf16
(`scripts/compile_probe.py` times this, the eager and the compiled autograd update at the
small preset's sizes and says whether this holds), delete `flat_update`, `flat_buffers` and
`flat_backward`, and `Execution.fast` on a CPU becomes the compiled autograd update.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import torch
from torch import nn

from seqrank.agents.sac.flat_backward import Layer, backward, forward, head_backward, min_gradient
from seqrank.agents.sac.flat_buffers import FlatAdam, FlatNet, FlatViews, flatten, views
from seqrank.agents.sac.networks import squashed_gaussian
from seqrank.buffer import Batch

COMPUTE_DTYPES = {"fp32": torch.float32, "bf16": torch.bfloat16}


class FlatAgent(Protocol):
    """The parts of a SAC agent (`agents.sac.SAC`) its flat update reads and steps: the
    critic and its target are `StackedTwinCritic`s."""

    @property
    def actor(self) -> nn.Module: ...
    @property
    def critic(self) -> nn.Module: ...
    @property
    def critic_target(self) -> nn.Module: ...
    @property
    def actor_opt(self) -> torch.optim.Adam: ...
    @property
    def critic_opt(self) -> torch.optim.Adam: ...
    @property
    def alpha_opt(self) -> torch.optim.Adam: ...
    @property
    def log_alpha(self) -> torch.Tensor: ...
    @property
    def target_entropy(self) -> float: ...
    @property
    def precision(self) -> str: ...
    @property
    def discount(self) -> float: ...


class FlatSACUpdate:
    """The update of `SAC._step` on flat buffers, for a CPU; see the module's docstring."""

    def __init__(self, agent: FlatAgent):
        self.agent = agent
        self.dtype = COMPUTE_DTYPES.get(agent.precision, torch.float32)
        actor = list(agent.actor.parameters())
        critic, target = list(agent.critic.parameters()), list(agent.critic_target.parameters())
        size = sum(p.numel() for p in critic)
        both = torch.empty(2 * size)  # critic then target: one cast for both
        flatten(critic, both[:size])
        flatten(target, both[size:])
        actor_flat = torch.empty(sum(p.numel() for p in actor))
        flatten(actor, actor_flat)
        self.critic_size = size
        self.critics = FlatNet(both, [*critic, *target], self.dtype)
        self.actor = FlatNet(actor_flat, actor, self.dtype)
        self.critic_adam = FlatAdam(agent.critic_opt, both[:size])
        self.actor_adam = FlatAdam(agent.actor_opt, actor_flat)
        self.alpha_adam = FlatAdam(agent.alpha_opt, agent.log_alpha.detach().view(1))
        self.critic_grad = self._grad_buffer(self.critic_adam)
        self.actor_grad = self._grad_buffer(self.actor_adam)
        self.critic_layers, self.target_layers = self._critic_layers(len(critic) // 2)
        self.actor_layers = self._actor_layers()
        self._views = [
            FlatViews.of(name, self._parameters_of(name))
            for name in ("actor", "critic", "critic_target", "log_alpha")
        ]

    def check_views(self) -> None:
        """Raises RuntimeError if a module's parameter no longer views its flat buffer."""
        for hooked in self._views:
            hooked.check()

    def _parameters_of(self, name: str) -> Callable[[], list[tuple[str, torch.Tensor]]]:
        """The agent's `name` (a module or the temperature) as named tensors, read anew at
        each call: a module replaced on the agent is seen too."""

        def current() -> list[tuple[str, torch.Tensor]]:
            part = getattr(self.agent, name)
            return [(name, part)] if isinstance(part, torch.Tensor) else [*part.named_parameters()]

        return current

    def _grad_buffer(self, adam: FlatAdam) -> torch.Tensor:
        return adam.grad if self.dtype == adam.grad.dtype else adam.grad.to(self.dtype)

    def _critic_layers(self, depth: int) -> tuple[list[Layer], list[Layer]]:
        """The stacked critic's (2, in, out) weights and (2, 1, out) biases, as stored."""
        weights = self.critics.compute_views
        grads = views(self.critic_grad, weights[: 2 * depth])
        critic = [
            Layer(weights[i], weights[depth + i], grads[i], grads[depth + i], False)
            for i in range(depth)
        ]
        target = [  # no gradient is ever taken: the gradient fields are the critic's, unused
            Layer(weights[2 * depth + i], weights[3 * depth + i], grads[i], grads[depth + i], False)
            for i in range(depth)
        ]
        return critic, target

    def _actor_layers(self) -> list[Layer]:
        """nn.Linear's (out, in) weights seen as (1, in, out) for the product."""
        weights, grads = self.actor.compute_views, views(self.actor_grad, self.actor.params)
        return [
            Layer(
                weights[i].unsqueeze(0).transpose(1, 2),
                weights[i + 1].view(1, 1, -1),
                grads[i].unsqueeze(0),
                grads[i + 1].view(1, 1, -1),
                True,
            )
            for i in range(0, len(weights), 2)
        ]

    def soft_update(self, tau: float) -> None:
        """target <- (1 - tau) target + tau critic: one lerp over the flat buffers."""
        size = self.critic_size
        self.critics.master[size:].lerp_(self.critics.master[:size], tau)

    def adopt_optimiser_state(self) -> None:
        """After a checkpoint is loaded: its Adam state into the flat buffers."""
        for flat_adam in (self.critic_adam, self.actor_adam, self.alpha_adam):
            flat_adam.adopt()

    def _q(self, layers: list[Layer], obs: torch.Tensor, action: torch.Tensor) -> tuple[
        torch.Tensor, list[torch.Tensor]
    ]:  # fmt: skip
        x = torch.cat([obs, action], dim=-1).to(self.dtype).unsqueeze(0).expand(2, -1, -1)
        q, inputs = forward(layers, x)
        return q.float(), inputs

    def step(
        self, batch: Batch, next_noise: torch.Tensor, noise: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Critic, actor and temperature steps; the critic's and actor's losses."""
        with torch.no_grad():
            self.critics.cast()
            self.actor.cast()
            rows = len(batch.obs)
            states = torch.cat([batch.next_obs, batch.obs]).to(self.dtype).unsqueeze(0)
            head, actor_inputs = forward(self.actor_layers, states)
            head = head[0].float()
            alpha = self.agent.log_alpha.detach().exp()
            critic_loss = self._critic_step(batch, head[:rows], next_noise, alpha)
            self.critics.cast(self.critic_size)  # the stepped critic for the actor's loss
            actor_inputs = [x[:, rows:] for x in actor_inputs]
            actor_loss, log_prob = self._actor_step(batch, head[rows:], noise, alpha, actor_inputs)
            entropy_gap = -log_prob - self.agent.target_entropy
            self.alpha_adam.grad.copy_((alpha * entropy_gap.mean()).view(1))
            self.alpha_adam.step()
        return critic_loss, actor_loss

    def _critic_step(
        self, batch: Batch, next_head: torch.Tensor, next_noise: torch.Tensor, alpha: torch.Tensor
    ) -> torch.Tensor:
        next_action, next_log_prob, _ = squashed_gaussian(next_head, next_noise)
        target_q, _ = self._q(self.target_layers, batch.next_obs, next_action)
        soft_value = torch.minimum(target_q[0], target_q[1]) - alpha * next_log_prob
        target = batch.reward + self.agent.discount * batch.not_done * soft_value
        q, inputs = self._q(self.critic_layers, batch.obs, batch.action)
        error = q - target
        grad_q = (error * (2 / len(batch.obs))).to(self.dtype)  # of the summed mean squares
        backward(self.critic_layers, inputs, grad_q, True)
        self._to_master_grad(self.critic_grad, self.critic_adam)
        self.critic_adam.step()
        return error.square().mean(dim=(1, 2)).sum()

    def _actor_step(
        self, batch: Batch, head: torch.Tensor, noise: torch.Tensor, alpha: torch.Tensor,
        inputs: list[torch.Tensor],
    ) -> tuple[torch.Tensor, torch.Tensor]:  # fmt: skip
        rows = len(head)
        action, log_prob, _ = squashed_gaussian(head, noise)
        q, critic_inputs = self._q(self.critic_layers, batch.obs, action)
        actor_loss = (alpha * log_prob - torch.minimum(q[0], q[1])).mean()
        grad_q = min_gradient(q, -1 / rows).to(self.dtype)
        grad_input = backward(self.critic_layers, critic_inputs, grad_q, False)
        assert grad_input is not None
        grad_action = grad_input.float().sum(0)[:, batch.obs.shape[1] :]
        grad_head = head_backward(head, noise, action, grad_action, alpha / rows)
        backward(self.actor_layers, inputs, grad_head.to(self.dtype).unsqueeze(0), True)
        self._to_master_grad(self.actor_grad, self.actor_adam)
        self.actor_adam.step()
        return actor_loss, log_prob

    @staticmethod
    def _to_master_grad(grad: torch.Tensor, adam: FlatAdam) -> None:
        if grad is not adam.grad:
            adam.grad.copy_(grad)
