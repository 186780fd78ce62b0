"""The flat update's forward and written backward passes: a stack of ReLU MLPs (the twin
critics, or the actor as a stack of one) and the squashed Gaussian's head.

An MLP's layer i, for each network of the stack, with rows as the batch:

    z_i = x_i W_i + b_i,    x_{i+1} = relu(z_i)    (no ReLU after the last layer)

and back from g_last = dL/dz_last:

    dL/dW_i = x_i^T g_i     (nn.Linear's stored (out, in) layout: g_i^T x_i)
    dL/db_i = sum over rows of g_i
    dL/dx_i = g_i W_i^T
    g_{i-1} = dL/dx_i where x_i > 0, else 0    (x_i = relu(z_{i-1}))

The squashed Gaussian (`networks.squashed_gaussian`) from the head (mu, r), noise e and
h = (LOG_STD_MAX - LOG_STD_MIN) / 2:

    s = LOG_STD_MIN + h (tanh(r) + 1),    u = mu + exp(s) e,    a = tanh(u)
    log pi = sum_j (-e_j^2 / 2 - s_j - log(2 pi) / 2 - log(1 - a_j^2))

so, from dL/da and dL/dlog pi:

    dL/du  = dL/da (1 - a^2) + 2 a dL/dlog pi     (d -log(1 - tanh(u)^2) / du = 2 tanh(u))
    dL/dmu = dL/du
    dL/ds  = dL/du exp(s) e - dL/dlog pi
    dL/dr  = dL/ds h (1 - tanh(r)^2)

Each is held to autograd in `tests/agents/test_flat_update.py`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from seqrank.agents.sac.networks import LOG_STD_MAX, LOG_STD_MIN

_relu_backward = torch.ops.aten.threshold_backward


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
    Gaussian's action and of its log-probability (the formulas in the module's docstring)."""
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
