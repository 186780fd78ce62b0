"""IQL's update against numbers worked out by hand, not against a second run of the code.

Every network is made constant: its last hidden layer's units are dead (weights 0, bias -1
under a ReLU), so it outputs its last bias and only that bias has a gradient. Adam's first
step then moves each bias by exactly its learning rate against the sign of its gradient
(m / sqrt(v) = +-1), and every quantity of one update has a closed form:
    V's loss      mean(w_tau (q' - v)^2), q' = min(Q1', Q2'), w_tau = tau if q' > v else 1 - tau
    the weights   min(exp(beta (q' - v_new)), 100), v_new = v + lr_v (V rises: q' > v)
    pi's loss     -mean(weight * log N(a; tanh(mean), exp(log_std)))
    Q's target    y = r + gamma (1 - terminal) v_new
    Q' after      (1 - 0.005) Q' + 0.005 (Q - lr_q sign(mean 2 (Q - y)))
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import torch

from seqrank.agents.iql import (
    IQL,
    TwinQ,
    advantage_weights,
    cosine_rate,
    expectile_loss,
    q_target,
)
from seqrank.agents.iql_settings import IQLSettings
from seqrank.agents.networks import mlp
from seqrank.buffer import Batch

OBS, ACT, ROWS = 3, 2, 5
GAMMA, TAU, RATE = 0.9, 0.7, 0.005
LR_ACTOR, LR_CRITIC, LR_VALUE = 1e-3, 2e-3, 3e-3
TARGET_Q, CRITIC_Q, VALUE = (1.5, 2.5), (0.7, -0.4), 0.9
MEAN_BIAS, LOG_STD = (0.4, -0.8), (-0.5, 0.2)


def settings(temperature: float) -> IQLSettings:
    return IQLSettings(
        hidden=8,
        layers=2,
        actor_lr=LR_ACTOR,
        critic_lr=LR_CRITIC,
        value_lr=LR_VALUE,
        discount=GAMMA,
        expectile=TAU,
        temperature=temperature,
        target_rate=RATE,
        decay_steps=100,
    )


def make_constant(net: torch.nn.Sequential, bias: float | tuple[float, ...]) -> None:
    """The net outputs `bias` whatever its input: its last hidden layer's ReLUs are dead."""
    with torch.no_grad():
        hidden, last = net[-3], net[-1]
        hidden.weight.zero_()
        hidden.bias.fill_(-1.0)
        last.bias.copy_(torch.as_tensor(bias, dtype=torch.float32))


def make_critics_constant(critic: TwinQ, biases: tuple[float, float]) -> None:
    """Each of the two critics outputs its own bias: their last hidden layer is dead."""
    with torch.no_grad():
        critic.weights[-2].zero_()
        critic.biases[-2].fill_(-1.0)
        critic.biases[-1].copy_(torch.tensor(biases).reshape(2, 1, 1))


def output_biases(critic: TwinQ) -> list[float]:
    return critic.biases[-1].detach().flatten().tolist()


def constant_agent(temperature: float) -> IQL:
    torch.manual_seed(0)
    agent = IQL(OBS, ACT, settings(temperature), torch.device("cpu"))
    for critic, biases in ((agent.critic, CRITIC_Q), (agent.critic_target, TARGET_Q)):
        make_critics_constant(critic, biases)
    make_constant(agent.value, VALUE)
    make_constant(agent.actor.net, MEAN_BIAS)
    with torch.no_grad():
        agent.actor.log_std.copy_(torch.tensor(LOG_STD))
    return agent


def batch() -> Batch:
    g = torch.Generator().manual_seed(3)
    obs, next_obs = torch.randn(ROWS, OBS, generator=g), torch.randn(ROWS, OBS, generator=g)
    action = torch.rand(ROWS, ACT, generator=g) * 2 - 1
    reward = torch.tensor([[1.0], [-2.0], [0.5], [0.0], [3.0]])
    not_done = torch.tensor([[1.0], [1.0], [0.0], [1.0], [0.0]])  # rows 2 and 4 terminal
    return Batch(obs, action, reward, next_obs, not_done)


def gaussian_log_prob(actions: np.ndarray) -> np.ndarray:
    """log N(a; tanh(mean bias), exp(log_std)) per row, the density written out."""
    total = np.zeros(len(actions))
    for j, (bias, log_std) in enumerate(zip(MEAN_BIAS, LOG_STD, strict=True)):
        z = (actions[:, j] - math.tanh(bias)) / math.exp(log_std)
        total += -0.5 * z**2 - log_std - 0.5 * math.log(2 * math.pi)
    return total


def hand_update(temperature: float) -> dict[str, float | np.ndarray]:
    b = batch()
    r, not_done = b.reward.numpy()[:, 0], b.not_done.numpy()[:, 0]
    q = min(TARGET_Q)
    diff = q - VALUE
    assert diff > 0  # V sits below the target: the tau side of the expectile loss
    value_loss = TAU * diff**2
    value_new = VALUE + LR_VALUE  # the loss falls as V rises
    weight = min(math.exp(temperature * (q - value_new)), 100.0)
    actor_loss = -weight * gaussian_log_prob(b.action.numpy().astype(np.float64)).mean()
    y = r + GAMMA * not_done * value_new
    critic_loss = float(np.mean([(c - y) ** 2 for c in CRITIC_Q], axis=1).sum())
    critic_new = [c - LR_CRITIC * np.sign(np.mean(2 * (c - y))) for c in CRITIC_Q]
    target_new = [(1 - RATE) * t + RATE * c for t, c in zip(TARGET_Q, critic_new, strict=True)]
    return {
        "value_loss": value_loss,
        "value_new": value_new,
        "weight": weight,
        "actor_loss": actor_loss,
        "critic_loss": critic_loss,
        "target_new": np.array(target_new),
    }


@pytest.mark.parametrize("temperature", [3.0, 10.0], ids=["weighted", "clipped"])
def test_one_update_matches_the_losses_and_steps_worked_out_by_hand(temperature):
    agent = constant_agent(temperature)
    agent.update(batch())
    expected = hand_update(temperature)
    got = agent.last_metrics

    assert got["value_loss"] == pytest.approx(expected["value_loss"], rel=1e-5)
    # the wrong side of the expectile gives another loss: the check can tell
    assert abs((1 - TAU) * (min(TARGET_Q) - VALUE) ** 2 - expected["value_loss"]) > 0.05
    assert float(agent.value[-1].bias.detach()) == pytest.approx(expected["value_new"], abs=1e-6)
    assert got["weight_mean"] == pytest.approx(expected["weight"], rel=1e-5)
    assert got["weight_clipped"] == (1.0 if temperature == 10.0 else 0.0)
    assert got["actor_loss"] == pytest.approx(expected["actor_loss"], rel=1e-5)
    assert got["critic_loss"] == pytest.approx(expected["critic_loss"], rel=1e-5)
    np.testing.assert_allclose(
        output_biases(agent.critic_target), expected["target_new"], atol=1e-6
    )


def test_the_weights_of_the_clipped_case_are_the_clip_and_the_unclipped_ones_are_not():
    assert hand_update(10.0)["weight"] == 100.0
    assert 1.0 < hand_update(3.0)["weight"] < 100.0


def test_the_expectile_loss_and_its_gradient_by_hand():
    diff = torch.tensor([-2.0, -0.5, 0.0, 0.5, 3.0], requires_grad=True)
    loss = expectile_loss(diff, 0.8)
    loss.sum().backward()
    by_hand = [0.2 * 4.0, 0.2 * 0.25, 0.0, 0.8 * 0.25, 0.8 * 9.0]
    np.testing.assert_allclose(loss.detach().numpy(), by_hand, rtol=1e-6)
    gradient = [2 * 0.2 * -2.0, 2 * 0.2 * -0.5, 0.0, 2 * 0.8 * 0.5, 2 * 0.8 * 3.0]
    np.testing.assert_allclose(diff.grad.numpy(), gradient, rtol=1e-6)
    # expectile 0.5 is half the squared error: V would regress to Q's mean
    np.testing.assert_allclose(expectile_loss(diff, 0.5).detach(), 0.5 * diff.detach() ** 2)


def test_the_q_target_bootstraps_only_where_the_episode_goes_on():
    reward = torch.tensor([[1.0], [2.0]])
    not_done = torch.tensor([[1.0], [0.0]])
    next_value = torch.tensor([[10.0], [10.0]])
    target = q_target(reward, not_done, next_value, 0.99)
    np.testing.assert_allclose(target.numpy()[:, 0], [1.0 + 0.99 * 10.0, 2.0])


def test_advantage_weights_exponentiate_beta_times_the_advantage_and_clip_at_100():
    q = torch.tensor([1.0, 1.0, 1.0, 5.0])
    v = torch.tensor([1.0, 2.0, 0.5, 0.0])
    got = advantage_weights(q, v, 3.0, 100.0).numpy()
    np.testing.assert_allclose(got, [1.0, math.exp(-3.0), math.exp(1.5), 100.0], rtol=1e-6)


def test_the_actor_rate_falls_along_a_cosine_to_zero():
    assert cosine_rate(3e-4, 0, 1000) == pytest.approx(3e-4)
    assert cosine_rate(3e-4, 500, 1000) == pytest.approx(1.5e-4)
    assert cosine_rate(3e-4, 1000, 1000) == pytest.approx(0.0, abs=1e-12)
    assert cosine_rate(3e-4, 5000, 1000) == pytest.approx(0.0, abs=1e-12)
    assert cosine_rate(3e-4, 5000, 0) == 3e-4  # no schedule


def test_acting_reads_raw_observations_through_the_datasets_scale():
    torch.manual_seed(0)
    mean, std = np.array([1.0, -2.0, 0.5]), np.array([2.0, 0.5, 1.0])
    agent = IQL(OBS, ACT, settings(3.0), torch.device("cpu"), mean, std)
    obs = np.array([3.0, -1.0, 0.0], np.float32)
    g = torch.Generator()
    with torch.no_grad():
        expected = torch.tanh(agent.actor.net(torch.tensor((obs - mean) / std).float()))
    np.testing.assert_allclose(agent.act(obs, True, g), expected.numpy(), rtol=1e-5)
    drawn = agent.act(obs, False, g)
    assert drawn.shape == (ACT,) and np.all(np.abs(drawn) <= 1.0)
    assert not np.allclose(drawn, expected.numpy())


def test_state_dict_round_trip_gives_the_same_next_update():
    first = constant_agent(3.0)
    first.update(batch())
    second = IQL(OBS, ACT, settings(3.0), torch.device("cpu"))
    second.load_state_dict(copy.deepcopy(first.state_dict()))  # as a checkpoint file would
    first.update(batch())
    second.update(batch())
    assert first.last_metrics == second.last_metrics
    assert second.updates == 2


def test_the_twin_critic_is_two_mlps_drawn_as_two_separate_networks_would_be():
    torch.manual_seed(5)
    separate = [mlp(OBS + ACT, 8, 2, 1) for _ in range(2)]
    torch.manual_seed(5)
    twin = TwinQ(OBS, ACT, 8, 2)
    obs, action = torch.randn(7, OBS), torch.rand(7, ACT) * 2 - 1
    got = twin(obs, action)
    assert got.shape == (2, 7, 1)
    for member, net in enumerate(separate):
        torch.testing.assert_close(got[member], net(torch.cat([obs, action], -1)))
    # the members differ: a twin that ran one network twice would not
    assert not torch.allclose(got[0], got[1])


def test_a_checkpoint_of_two_separate_critics_is_refused_in_words():
    agent = constant_agent(3.0)
    state = agent.state_dict()
    state["critic"] = {"q1.0.weight": torch.zeros(1), "q2.0.weight": torch.zeros(1)}
    with pytest.raises(ValueError, match="two networks"):
        agent.load_state_dict(state)
