"""The fast path's SAC update on a CPU: the same arithmetic as autograd's, with fewer operations.

On a CPU the update's cost beyond its matrix products is per operation (autograd's
bookkeeping, a cast per weight per use under autocast, an optimiser call per tensor), not
arithmetic. So here each network's weights, gradients and Adam moments live in one flat
buffer (the modules' parameters are views of it): one cast gives a network's weights in
the compute precision, one fused Adam call steps it, one lerp moves the target critic. The
backward passes are written by hand (two ReLU MLPs and the squashed Gaussian's head) and the
actor runs once on the next and current observations together (its weights do not change
before its own step). `tests/agents/test_flat_update.py` holds it to autograd's update.

The `torch.optim.Adam` objects stay as the record of Adam's state (checkpoints read them):
their per-parameter moments are views of the flat moments, and they are never stepped here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import torch
from torch import nn
from torch.optim.adam import adam

from seqrank.agents.networks import LOG_STD_MAX, LOG_STD_MIN, squashed_gaussian
from seqrank.buffer import Batch

COMPUTE_DTYPES = {"fp32": torch.float32, "bf16": torch.bfloat16}
_relu_backward = torch.ops.aten.threshold_backward


def flatten(params: Sequence[nn.Parameter], flat: torch.Tensor) -> None:
    """Copies `params` into `flat` and makes each parameter a view of its slice."""
    offset = 0
    with torch.no_grad():
        for param in params:
            view = flat[offset : offset + param.numel()].view_as(param)
            view.copy_(param)
            param.data = view
            offset += param.numel()


def views(flat: torch.Tensor, like: Sequence[torch.Tensor]) -> list[torch.Tensor]:
    """`flat` cut into tensors shaped as `like`, in order."""
    sizes = [t.numel() for t in like]
    return [part.view_as(t) for part, t in zip(flat.split(sizes), like, strict=True)]


class FlatAdam:
    """Adam (torch's fused kernel) on one flat parameter buffer, its state recorded in a
    `torch.optim.Adam` as views, so checkpoints and resets see one state."""

    def __init__(self, optimizer: torch.optim.Adam, flat: torch.Tensor):
        self.optimizer, self.flat = optimizer, flat
        self.params: list[torch.Tensor] = list(optimizer.param_groups[0]["params"])
        self.grad = torch.zeros_like(flat)
        self.exp_avg, self.exp_avg_sq = torch.zeros_like(flat), torch.zeros_like(flat)
        self.steps = torch.zeros((), dtype=torch.float32)
        self._recorded: torch.Tensor | None = None  # the first parameter's recorded moment
        optimizer.step = _stepped_elsewhere  # type: ignore[method-assign]

    def adopt(self) -> None:
        """Takes the optimiser's recorded state (after a load) into the flat buffers; an
        empty record stays empty until the first step, as with torch's Adam."""
        state = self.optimizer.state
        if not state:
            return
        with torch.no_grad():
            for moment in ("exp_avg", "exp_avg_sq"):
                values = [state[p][moment].clone() for p in self.params]
                for view, value in zip(
                    views(getattr(self, moment), self.params), values, strict=True
                ):
                    view.copy_(value)
            self.steps.copy_(state[self.params[0]]["step"])
        self._record()

    def _record(self) -> None:
        moments = views(self.exp_avg, self.params), views(self.exp_avg_sq, self.params)
        for param, avg, avg_sq in zip(self.params, *moments, strict=True):
            self.optimizer.state[param] = {"step": self.steps, "exp_avg": avg, "exp_avg_sq": avg_sq}
        self._recorded = self.optimizer.state[self.params[0]]["exp_avg"]

    def step(self) -> None:
        """One Adam step on `grad` (fresh state on the first step or after a reset; a
        record replaced behind its back, e.g. by the optimiser's own `load_state_dict`,
        is taken in first)."""
        state = self.optimizer.state
        if not state:
            self.exp_avg.zero_()
            self.exp_avg_sq.zero_()
            self.steps.zero_()
            self._record()
        elif state.get(self.params[0], {}).get("exp_avg") is not self._recorded:
            self.adopt()
        group = self.optimizer.param_groups[0]
        beta1, beta2 = group["betas"]
        adam(
            [self.flat], [self.grad], [self.exp_avg], [self.exp_avg_sq], [], [self.steps],
            fused=True, amsgrad=False, beta1=beta1, beta2=beta2, lr=group["lr"],
            weight_decay=group["weight_decay"], eps=group["eps"], maximize=False,
        )  # fmt: skip


def _stepped_elsewhere(*args: object, **kwargs: object) -> None:
    raise RuntimeError(
        "this optimiser only records the Adam state of a flat update "
        "(seqrank.agents.flat_update), which steps the weights itself; stepping it too "
        "would move them twice"
    )


@dataclass(frozen=True)
class Layer:
    """One linear layer of a stack of `n` networks: weight (n, in, out) as used in the
    product, bias (n, 1, out), and where the weight's gradient goes in its stored layout."""

    weight: torch.Tensor
    bias: torch.Tensor
    grad_weight: torch.Tensor
    grad_bias: torch.Tensor
    stored_out_in: bool  # nn.Linear's (out, in) layout rather than (in, out)


def forward(layers: Sequence[Layer], x: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
    """The MLP's output (ReLU between layers) and each layer's input, kept for `backward`."""
    inputs = []
    for i, layer in enumerate(layers):
        inputs.append(x)
        x = torch.baddbmm(layer.bias, x, layer.weight)
        if i < len(layers) - 1:
            x = torch.relu_(x)
    return x, inputs


def backward(
    layers: Sequence[Layer], inputs: Sequence[torch.Tensor], grad: torch.Tensor, weights: bool
) -> torch.Tensor | None:
    """Back through the MLP from its output's gradient. With `weights`, the weights'
    gradients are written in place (and None returned); without, the gradient of the input
    is returned and no weight gradient is made (the actor's loss needs the critic's so)."""
    for i in reversed(range(len(layers))):
        layer, x = layers[i], inputs[i]
        if weights:
            if layer.stored_out_in:
                torch.bmm(grad.transpose(1, 2), x, out=layer.grad_weight)
            else:
                torch.bmm(x.transpose(1, 2), grad, out=layer.grad_weight)
            torch.sum(grad, dim=1, keepdim=True, out=layer.grad_bias)
            if i == 0:
                return None
        grad_input = torch.bmm(grad, layer.weight.transpose(1, 2))
        if i == 0:
            return grad_input
        grad = _relu_backward(grad_input, x, 0)
    raise ValueError("an MLP needs at least one layer")


def head_backward(
    head: torch.Tensor, noise: torch.Tensor, action: torch.Tensor, grad_action: torch.Tensor,
    grad_log_prob: torch.Tensor,
) -> torch.Tensor:  # fmt: skip
    """The gradient of the actor's head (mean, raw log-std) from those of the squashed
    Gaussian's action and of its log-probability (`networks.squashed_gaussian`):
    d action / d pre_tanh = 1 - action^2, d log_prob / d pre_tanh = 2 action,
    d log_prob / d log_std = -1 besides its path through pre_tanh = mean + std * noise."""
    raw_log_std = head[:, action.shape[1] :]
    squashed = torch.tanh(raw_log_std)
    half_range = 0.5 * (LOG_STD_MAX - LOG_STD_MIN)
    std = torch.exp(LOG_STD_MIN + half_range * (squashed + 1))
    grad_pre = grad_action * (1 - action * action) + (2 * grad_log_prob) * action
    grad_log_std = grad_pre * std * noise - grad_log_prob
    grad_raw = grad_log_std * (half_range * (1 - squashed * squashed))
    return torch.cat([grad_pre, grad_raw], dim=1)


def min_gradient(q: torch.Tensor, scale: float) -> torch.Tensor:
    """`scale` times the gradient of min(q[0], q[1]) with respect to q, ties split in half
    (as autograd's `torch.minimum`)."""
    first = (q[0] < q[1]).to(q.dtype) + 0.5 * (q[0] == q[1]).to(q.dtype)
    return torch.stack([first, 1 - first]) * scale


class FlatNet:
    """A network's weights flattened: fp32 master copy, a copy in the compute precision and
    its gradient buffer (the same tensors as the fp32 ones when computing in fp32)."""

    def __init__(self, master: torch.Tensor, params: Sequence[torch.Tensor], dtype: torch.dtype):
        self.master, self.params = master, params
        low = dtype != master.dtype
        self.compute = torch.empty_like(master, dtype=dtype) if low else master
        self.compute_views = views(self.compute, params)

    def cast(self, size: int | None = None) -> None:
        """The compute copy brought up to date (its first `size` values only, if given)."""
        if self.compute is not self.master:
            self.compute[:size].copy_(self.master[:size])


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
