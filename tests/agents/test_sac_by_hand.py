"""SAC's update against numbers worked out by hand, not against a second run of the code.

The networks are made constant (last layers' weights zero), so every quantity of the
update has a closed form: the critics output their biases, the actor's head outputs its
bias (the mean and the raw log-std), and the soft target value of SPEC section 1 is
    y = r + gamma * not_done * (min(Q1', Q2') - alpha * log pi(a'|s')).
The reference and the fast autograd update share `_target_value`, so comparing them cannot
see a term dropped from it; this can. Each test runs on the three updates: the reference,
the fast path's autograd update (stacked critics, fused Adam: CUDA's, here on a CPU) and
the flat update (the fast path on a CPU, its backward written by hand), so a slip in either
of the flat update's own formulas is caught here too.

Adam's first step moves each weight by exactly lr against the sign of its gradient
(m / sqrt(v) = +-1 at step one, after the bias correction), so a step's direction worked
out by hand gives the weight after it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from seqrank.agents.sac import SAC, Execution, SACSettings
from seqrank.agents.sac.critics import canonical_weights, load_canonical_weights
from seqrank.agents.sac.networks import LOG_STD_MAX, LOG_STD_MIN
from seqrank.buffer import Batch

OBS, ACT, ROWS = 4, 2, 5
ALPHA, GAMMA = 0.3, 0.9
SETTINGS = SACSettings(
    hidden=16,
    layers=2,
    actor_lr=1e-3,
    critic_lr=1e-3,
    alpha_lr=1e-3,
    init_temperature=ALPHA,
    discount=GAMMA,
    tau=0.005,
    target_update_every=1,
)
MEANS, LOG_STDS = (0.5, -0.3), (-3.0, -2.0)  # narrow: entropy below the target's -2
TARGET_Q, CRITIC_Q = (1.5, 2.5), (0.7, -0.4)
CPU = torch.device("cpu")
PATHS = pytest.mark.parametrize(
    "execution",
    [
        Execution(),
        Execution(stacked_critics=True, fused_adam=True),
        Execution.fast(CPU, "fp32"),
    ],
    ids=["reference", "autograd-fast", "flat"],
)


def raw_log_std(log_std: float) -> float:
    """The actor head's value that the squashing maps to `log_std`."""
    return math.atanh(2 * (log_std - LOG_STD_MIN) / (LOG_STD_MAX - LOG_STD_MIN) - 1)


def constant_agent(execution: Execution) -> SAC:
    torch.manual_seed(0)
    agent = SAC(OBS, ACT, SETTINGS, CPU, execution)
    with torch.no_grad():
        last = agent.actor.net[-1]
        last.weight.zero_()
        last.bias.copy_(torch.tensor([*MEANS, *(raw_log_std(s) for s in LOG_STDS)]))
    for critic, biases in ((agent.critic, CRITIC_Q), (agent.critic_target, TARGET_Q)):
        weights = canonical_weights(critic)
        last_layer = max(int(name.split(".")[1]) for name in weights)
        for member, bias in zip(("q1", "q2"), biases, strict=True):
            weights[f"{member}.{last_layer}.weight"].zero_()
            weights[f"{member}.{last_layer}.bias"].fill_(bias)
        load_canonical_weights(critic, weights)
    return agent


def log_prob_by_hand(noise: np.ndarray) -> np.ndarray:
    """log pi of tanh(mean + std * noise) per row: Gaussian density minus log|d tanh|."""
    total = np.zeros(len(noise))
    for j, (mean, log_std) in enumerate(zip(MEANS, LOG_STDS, strict=True)):
        pre_tanh = mean + math.exp(log_std) * noise[:, j]
        gaussian = -0.5 * noise[:, j] ** 2 - log_std - 0.5 * math.log(2 * math.pi)
        total += gaussian - np.log(1 - np.tanh(pre_tanh) ** 2)
    return total


def soft_target_by_hand(batch: Batch, next_noise: torch.Tensor) -> np.ndarray:
    """y per row: the target critics output their biases, the next action's log-prob is
    `log_prob_by_hand`'s."""
    r, not_done = batch.reward.numpy()[:, 0], batch.not_done.numpy()[:, 0]
    soft_value = min(TARGET_Q) - ALPHA * log_prob_by_hand(next_noise.numpy().astype(np.float64))
    return r + GAMMA * not_done * soft_value


def batch_and_noise() -> tuple[Batch, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(7)
    obs, next_obs = torch.randn(ROWS, OBS, generator=g), torch.randn(ROWS, OBS, generator=g)
    action = torch.rand(ROWS, ACT, generator=g) * 2 - 1
    reward = torch.tensor([[1.0], [-2.0], [0.5], [0.0], [3.0]])
    not_done = torch.tensor([[1.0], [1.0], [0.0], [1.0], [0.0]])
    next_noise = torch.randn(ROWS, ACT, generator=g) * 0.5
    noise = torch.randn(ROWS, ACT, generator=g) * 0.5
    return Batch(obs, action, reward, next_obs, not_done), next_noise, noise


@PATHS
def test_the_critic_loss_is_the_soft_bellman_error_worked_out_by_hand(execution):
    agent = constant_agent(execution)
    batch, next_noise, noise = batch_and_noise()
    agent.update_with_noise(batch, next_noise, noise)

    r, not_done = batch.reward.numpy()[:, 0], batch.not_done.numpy()[:, 0]
    target = soft_target_by_hand(batch, next_noise)
    loss = sum(np.mean((q - target) ** 2) for q in CRITIC_Q)
    assert agent.last_metrics["critic_loss"] == pytest.approx(loss, rel=1e-5)
    # without the entropy term the same batch gives another loss: the check can tell
    entropy_free = r + GAMMA * not_done * min(TARGET_Q)
    assert abs(loss - sum(np.mean((q - entropy_free) ** 2) for q in CRITIC_Q)) > 0.1


@PATHS
def test_the_temperature_steps_against_the_entropy_gap_by_hand(execution):
    """alpha's loss is alpha * mean(-log pi - target entropy); Adam's first step moves
    log alpha by lr against the sign of its gradient (m / sqrt(v) = +-1 at step one)."""
    agent = constant_agent(execution)
    batch, next_noise, noise = batch_and_noise()
    agent.update_with_noise(batch, next_noise, noise)
    # the temperature's loss uses the log-prob computed before the actor's step: the head
    # is still its bias there, so the closed form holds
    gap = float(np.mean(-log_prob_by_hand(noise.numpy().astype(np.float64)) + ACT))
    assert gap < 0  # the policy is narrower than the target entropy allows: alpha must rise
    expected = math.log(ALPHA) - SETTINGS.alpha_lr * math.copysign(1.0, ALPHA * gap)
    assert float(agent.log_alpha.detach()) == pytest.approx(expected, abs=1e-6)


def head_gradient_by_hand(noise: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The actor loss's gradient by the head's mean and by its log-std, per action
    dimension. L = mean(alpha log pi - min Q) with u = mean + exp(log_std) noise: only
    -log(1 - tanh(u)^2) of log pi depends on the mean (d/du = 2 tanh(u)); the log-std also
    enters as -log_std (d = -1) and through u (d u / d log_std = exp(log_std) noise)."""
    by_mean, by_log_std = np.zeros(ACT), np.zeros(ACT)
    for j, (mean, log_std) in enumerate(zip(MEANS, LOG_STDS, strict=True)):
        std = math.exp(log_std)
        squashed = np.tanh(mean + std * noise[:, j])
        by_mean[j] = ALPHA * np.mean(2 * squashed)
        by_log_std[j] = ALPHA * np.mean(-1 + 2 * squashed * std * noise[:, j])
    return by_mean, by_log_std


@PATHS
def test_the_actor_steps_along_the_log_probabilitys_gradient_by_hand(execution):
    """The actor's head bias after one update: the mean and the raw log-std (which moves as
    the log-std does: the squashing is increasing) each one lr against their gradient's
    sign. The critic's own step just before makes Q depend on the action by O(lr): too
    little to turn a sign worked out here (each gradient is at least 0.05 from zero)."""
    agent = constant_agent(execution)
    batch, next_noise, noise = batch_and_noise()
    agent.update_with_noise(batch, next_noise, noise)

    by_mean, by_log_std = head_gradient_by_hand(noise.numpy().astype(np.float64))
    assert min(abs(by_mean).min(), abs(by_log_std).min()) > 0.05
    assert (by_log_std < 0).all()  # the policy widens: its entropy is rewarded
    lr = SETTINGS.actor_lr
    start = [*MEANS, *(raw_log_std(s) for s in LOG_STDS)]
    expected = np.array(start) - lr * np.sign(np.concatenate([by_mean, by_log_std]))
    bias = agent.actor.net[-1].bias.detach().numpy()
    np.testing.assert_allclose(bias, expected, rtol=0, atol=1e-6)


@PATHS
def test_the_target_critic_moves_tau_of_the_way_to_the_stepped_critic(execution):
    """Each critic's output bias steps one lr against the sign of its loss's gradient,
    mean(2 (Q_k - y)); then, as the target is updated every update here, the target's
    bias becomes (1 - tau) target + tau critic."""
    agent = constant_agent(execution)
    batch, next_noise, noise = batch_and_noise()
    agent.update_with_noise(batch, next_noise, noise)

    target = soft_target_by_hand(batch, next_noise)
    lr, tau = SETTINGS.critic_lr, SETTINGS.tau
    stepped = [q - lr * math.copysign(1.0, np.mean(2 * (q - target))) for q in CRITIC_Q]
    moved = [(1 - tau) * t + tau * c for t, c in zip(TARGET_Q, stepped, strict=True)]
    for critic, expected in ((agent.critic, stepped), (agent.critic_target, moved)):
        weights = canonical_weights(critic)
        last_layer = max(int(name.split(".")[1]) for name in weights)
        for member, value in zip(("q1", "q2"), expected, strict=True):
            bias = float(weights[f"{member}.{last_layer}.bias"])
            assert bias == pytest.approx(value, abs=1e-6), (member, critic is agent.critic)
