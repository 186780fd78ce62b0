"""SAC's update with its gradients written out: the same arithmetic as `SAC._step`, without
autograd.

On a CPU a small SAC update is mostly overhead: autograd records a graph of about two
hundred small ops and walks it back, and the elementwise work between the matmuls costs as
much as they do. Here each gradient is the closed form of its layer (ReLU masks, the
squashed Gaussian's derivatives), the twin critics are one stacked batched matmul per layer,
and nothing is computed that the update does not use (no critic weight gradients in the
actor's step). Tested against the autograd update to float tolerance
(tests/agents/test_sac_manual.py).

The squashed Gaussian (`networks.squashed_gaussian`): pre = mean + std * noise, a = tanh(pre),
log pi = sum(-noise^2 / 2 - log std - log(2 pi) / 2) - sum(log(1 - a^2)); so
d log pi / d pre = 2 a and d log pi / d log std = -1 + 2 a * std * noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import torch

from seqrank.agents.networks import LOG_STD_MAX, LOG_STD_MIN

LOG_STD_SPAN = LOG_STD_MAX - LOG_STD_MIN
HALF_LOG_2PI = 0.5 * math.log(2 * math.pi)


@dataclass(frozen=True)
class Layers:
    """An MLP as its weights (in, out) and biases (1, out), stacked on a leading axis for
    the twin critics; ReLU between layers."""

    weights: list[torch.Tensor]
    biases: list[torch.Tensor]


def mlp_forward(layers: Layers, x: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
    """The output and each hidden layer's activation (what the backward pass reads)."""
    hidden = []
    last = len(layers.weights) - 1
    for i, (weight, bias) in enumerate(zip(layers.weights, layers.biases, strict=True)):
        x = torch.baddbmm(bias, x, weight) if weight.dim() == 3 else torch.addmm(bias, x, weight)
        if i < last:
            x = torch.relu_(x)
            hidden.append(x)
    return x, hidden


def mlp_backward(
    layers: Layers,
    x: torch.Tensor,
    hidden: list[torch.Tensor],
    grad_out: torch.Tensor,
    weight_grads: bool,
    input_grad: bool,
) -> tuple[list[torch.Tensor], list[torch.Tensor], torch.Tensor | None]:
    """Gradients of the weights and biases (if asked) and of the input (if asked)."""
    inputs = [x, *hidden]
    weight_g: list[torch.Tensor] = []
    bias_g: list[torch.Tensor] = []
    grad = grad_out
    for i in range(len(layers.weights) - 1, -1, -1):
        weight = layers.weights[i]
        if weight_grads:
            weight_g.append(inputs[i].transpose(-1, -2) @ grad)
            bias_g.append(grad.sum(-2, keepdim=True))
        if i == 0 and not input_grad:
            break
        grad = grad @ weight.transpose(-1, -2)
        if i > 0:
            grad = grad.mul_(inputs[i] > 0)
    weight_g.reverse()
    bias_g.reverse()
    return weight_g, bias_g, grad if input_grad else None


def squashed(head: torch.Tensor, noise: torch.Tensor) -> dict[str, torch.Tensor]:
    """The policy's action and log-probability, with what its derivatives need."""
    mean, raw_log_std = head.chunk(2, dim=-1)
    squash = torch.tanh(raw_log_std)
    log_std = LOG_STD_MIN + 0.5 * LOG_STD_SPAN * (squash + 1)
    std = log_std.exp()
    pre = mean + std * noise
    action = torch.tanh(pre)
    gauss = (-0.5 * noise.pow(2) - log_std - HALF_LOG_2PI).sum(-1, True)
    jacobian = (2 * (math.log(2) - pre - torch.nn.functional.softplus(-2 * pre))).sum(-1, True)
    return {
        "action": action,
        "log_prob": gauss - jacobian,
        "std_noise": std * noise,
        "squash": squash,
    }


def squashed_backward(
    policy: dict[str, torch.Tensor], grad_action: torch.Tensor, grad_log_prob: torch.Tensor
) -> torch.Tensor:
    """d loss / d head from d loss / d action (B, A) and d loss / d log pi (B, 1)."""
    action = policy["action"]
    grad_pre = grad_action * (1 - action * action) + grad_log_prob * 2 * action
    grad_log_std = grad_pre * policy["std_noise"] - grad_log_prob
    grad_raw = grad_log_std * (0.5 * LOG_STD_SPAN) * (1 - policy["squash"].pow(2))
    return torch.cat([grad_pre, grad_raw], dim=-1)


def actor_layers(net: torch.nn.Sequential) -> Layers:
    linear = [m for m in net if isinstance(m, torch.nn.Linear)]
    return Layers([m.weight.t() for m in linear], [m.bias.unsqueeze(0) for m in linear])


def critic_layers(critic: torch.nn.Module) -> Layers:
    return Layers(list(critic.weights), list(critic.biases))  # type: ignore[arg-type]


def _set_grads(params: list[torch.Tensor], grads: list[torch.Tensor]) -> None:
    for param, grad in zip(params, grads, strict=True):
        param.grad = grad.reshape(param.shape) if grad.shape != param.shape else grad


class Parts(Protocol):
    """What the update reads and steps of a SAC agent with stacked critics."""

    actor: torch.nn.Module
    critic: torch.nn.Module
    critic_target: torch.nn.Module
    log_alpha: torch.Tensor
    actor_opt: torch.optim.Optimizer
    critic_opt: torch.optim.Optimizer
    alpha_opt: torch.optim.Optimizer
    target_entropy: float


@torch.no_grad()
def manual_step(
    agent: Parts,
    batch: tuple[torch.Tensor, ...],
    next_noise: torch.Tensor,
    noise: torch.Tensor,
    discount: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One SAC update (critic, actor, temperature) from `batch` = (obs, action, reward,
    next_obs, not_done); returns the critic's and the actor's loss."""
    obs, action, reward, next_obs, not_done = batch
    rows = obs.shape[0]
    alpha = agent.log_alpha.exp()
    actor = actor_layers(agent.actor.net)  # type: ignore[arg-type]
    # the critic's target, from the target critic at the next state
    next_head, _ = mlp_forward(actor, next_obs)
    following = squashed(next_head, next_noise)
    target_in = torch.cat([next_obs, following["action"]], -1).expand(2, -1, -1)
    next_q, _ = mlp_forward(critic_layers(agent.critic_target), target_in)
    soft = torch.minimum(next_q[0], next_q[1]) - alpha * following["log_prob"]
    target = reward + discount * not_done * soft
    # the critic's step: both critics' squared error against it
    critic = critic_layers(agent.critic)
    critic_in = torch.cat([obs, action], -1).expand(2, -1, -1)
    q, hidden = mlp_forward(critic, critic_in)
    error = q - target
    critic_loss = error.pow(2).mean(dim=(1, 2)).sum()
    weight_g, bias_g, _ = mlp_backward(critic, critic_in, hidden, error * (2 / rows), True, False)
    _set_grads([*agent.critic.weights, *agent.critic.biases], weight_g + bias_g)
    agent.critic_opt.step()
    # the actor's step through the stepped critic: no critic weight gradients
    head, actor_hidden = mlp_forward(actor, obs)
    policy = squashed(head, noise)
    policy_in = torch.cat([obs, policy["action"]], -1).expand(2, -1, -1)
    q_pi, critic_hidden = mlp_forward(critic, policy_in)
    first_smaller = q_pi[0] <= q_pi[1]
    actor_loss = (alpha * policy["log_prob"] - torch.minimum(q_pi[0], q_pi[1])).mean()
    grad_q = torch.stack([first_smaller, ~first_smaller]).to(q_pi.dtype) * (-1 / rows)
    _, _, grad_in = mlp_backward(critic, policy_in, critic_hidden, grad_q, False, True)
    assert grad_in is not None
    grad_action = grad_in.sum(0)[:, obs.shape[1] :]
    grad_log_prob = (alpha / rows).expand_as(policy["log_prob"])
    grad_head = squashed_backward(policy, grad_action, grad_log_prob)
    weight_g, bias_g, _ = mlp_backward(actor, obs, actor_hidden, grad_head, True, False)
    linear = [m for m in agent.actor.net if isinstance(m, torch.nn.Linear)]
    _set_grads([m.weight for m in linear], [g.t().contiguous() for g in weight_g])
    _set_grads([m.bias for m in linear], bias_g)
    agent.actor_opt.step()
    # the temperature's step
    agent.log_alpha.grad = alpha * (-policy["log_prob"] - agent.target_entropy).mean()
    agent.alpha_opt.step()
    return critic_loss, actor_loss
