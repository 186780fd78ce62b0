"""The flat update (the fast path on a CPU) held to autograd: each hand-written backward
piece against autograd's gradient, and whole updates against the autograd update."""

from __future__ import annotations

import copy
from dataclasses import replace

import pytest
import torch
from test_sac_paths import ACT, CPU, OBS, ROWS, SETTINGS, random_batch

from seqrank.agents.sac import SAC, Execution
from seqrank.agents.sac.critics import StackedTwinCritic
from seqrank.agents.sac.flat_backward import Layer, backward, forward, head_backward, min_gradient
from seqrank.agents.sac.networks import Actor, squashed_gaussian

FLAT = Execution(stacked_critics=True, fused_adam=True, flat=True)


def test_the_fast_path_on_a_cpu_is_the_flat_update_and_only_there():
    assert Execution.fast(CPU, "bf16").flat
    assert not Execution.fast(torch.device("cuda"), "bf16").flat
    with pytest.raises(ValueError, match="flat update runs on a CPU with stacked critics"):
        SAC(OBS, ACT, SETTINGS, CPU, Execution(flat=True))


def test_the_squashed_gaussian_head_gradient_is_autograds():
    generator = torch.Generator().manual_seed(0)
    head = torch.randn((ROWS, 2 * ACT), generator=generator, dtype=torch.float64) * 2
    noise = torch.randn((ROWS, ACT), generator=generator, dtype=torch.float64)
    grad_action = torch.randn((ROWS, ACT), generator=generator, dtype=torch.float64)
    grad_log_prob = torch.tensor(0.37, dtype=torch.float64)
    head.requires_grad_(True)
    action, log_prob, _ = squashed_gaussian(head, noise)
    ((action * grad_action).sum() + grad_log_prob * log_prob.sum()).backward()
    assert head.grad is not None
    ours = head_backward(head.detach(), noise, action.detach(), grad_action, grad_log_prob)
    torch.testing.assert_close(ours, head.grad, rtol=1e-7, atol=1e-9)  # float64


def test_the_minimum_gradient_splits_ties_as_autograd_does():
    q = torch.tensor([[[1.0], [2.0], [3.0]], [[1.5], [2.0], [2.5]]], requires_grad=True)
    torch.minimum(q[0], q[1]).sum().mul(-0.25).backward()
    assert q.grad is not None
    torch.testing.assert_close(min_gradient(q.detach(), -0.25), q.grad)
    assert q.grad[:, 1].tolist() == [[-0.125], [-0.125]]  # the tie at row 1, split


def _autograd_layers(params: list[torch.Tensor], stored_out_in: bool) -> list[Layer]:
    """Layers over `params` themselves (weights, then biases of the same layer)."""
    layers = []
    for weight, bias in zip(params[0::2], params[1::2], strict=True):
        if stored_out_in:
            weight, bias = weight.unsqueeze(0).transpose(1, 2), bias.view(1, 1, -1)
        empty = torch.empty(0)
        layers.append(Layer(weight, bias, empty, empty, stored_out_in))
    return layers


@pytest.mark.parametrize("stored_out_in", [True, False], ids=["actor", "stacked-critic"])
def test_the_mlp_backward_gives_autograds_gradients(stored_out_in):
    torch.manual_seed(0)
    if stored_out_in:
        params = list(Actor(OBS, ACT, 16, 2).net.parameters())
        x = torch.randn(1, ROWS, OBS)
    else:
        critic = StackedTwinCritic(OBS, ACT, 16, 2)
        weights, biases = list(critic.weights), list(critic.biases)
        params = [t for pair in zip(weights, biases, strict=True) for t in pair]
        x = torch.randn(1, ROWS, OBS + ACT).expand(2, -1, -1)
    x.requires_grad_(True)
    out, inputs = forward(_autograd_layers(params, stored_out_in), x)
    grad_out = torch.randn_like(out)
    (out * grad_out).sum().backward()
    grads = [torch.empty_like(p) for p in params]
    layers = [
        Layer(
            layer.weight.detach(),
            layer.bias.detach(),
            gw.view_as(layer.weight.transpose(1, 2)) if stored_out_in else gw,
            gb.view_as(layer.bias),
            stored_out_in,
        )
        for layer, gw, gb in zip(
            _autograd_layers(params, stored_out_in), grads[0::2], grads[1::2], strict=True
        )
    ]
    detached = [i.detach() for i in inputs]
    assert backward(layers, detached, grad_out, weights=True) is None
    for ours, param in zip(grads, params, strict=True):
        torch.testing.assert_close(ours, param.grad, rtol=1e-5, atol=1e-6)
    grad_input = backward(layers, detached, grad_out, weights=False)
    torch.testing.assert_close(grad_input, x.grad, rtol=1e-5, atol=1e-6)


def _same_start(execution: Execution, layers: int = 2) -> tuple[SAC, SAC]:
    """An autograd agent (stacked critics, fused Adam) and a flat one, equal weights."""
    torch.manual_seed(0)
    settings = replace(SETTINGS, layers=layers)
    autograd = SAC(OBS, ACT, settings, CPU, replace(execution, flat=False))
    flat = SAC(OBS, ACT, settings, CPU, execution)
    flat.load_state_dict(autograd.state_dict())
    return autograd, flat


def _assert_same_state(actual: dict, expected: dict, tolerance: float) -> None:
    """Weights, temperature and every optimiser's moments and step."""
    for part in ("actor", "critic", "critic_target"):
        for name, value in expected[part].items():
            torch.testing.assert_close(actual[part][name], value, atol=tolerance, rtol=0)
    for optimiser in ("actor_opt", "critic_opt", "alpha_opt"):
        assert actual[optimiser]["step"] == expected[optimiser]["step"], optimiser
        for moment in ("exp_avg", "exp_avg_sq"):
            for name, value in expected[optimiser][moment].items():
                torch.testing.assert_close(
                    actual[optimiser][moment][name], value, atol=tolerance, rtol=1e-3
                )
    torch.testing.assert_close(actual["log_alpha"], expected["log_alpha"])


@pytest.mark.parametrize(
    ("precision", "layers"), [("fp32", 2), ("bf16", 2), ("fp32", 1), ("fp32", 3)]
)
def test_flat_updates_follow_the_autograd_updates(precision, layers):
    """Same batches and noise, a critic reset among them: losses, weights, temperature and
    Adam's state agree (bf16: both round the same products to bf16, so only the order of
    sums differs)."""
    autograd, flat = _same_start(replace(FLAT, precision=precision), layers)
    generator = torch.Generator().manual_seed(1)
    for update in range(6):  # three soft target updates among them
        batch = random_batch(generator)
        noises = [torch.randn((ROWS, ACT), generator=generator) for _ in range(2)]
        if update == 3:
            torch.manual_seed(7)  # the reset draws fresh weights from the global generator
            autograd.reset_critic()
            torch.manual_seed(7)
            flat.reset_critic()
        autograd.update_with_noise(batch, *noises)
        flat.update_with_noise(batch, *noises)
        for name, value in autograd.last_metrics.items():
            assert flat.last_metrics[name] == pytest.approx(value, rel=1e-4, abs=1e-6), name
    tolerance = 1e-6 if precision == "fp32" else 1e-3
    _assert_same_state(flat.state_dict(), autograd.state_dict(), tolerance)
    assert flat.state_dict()["actor_opt"]["step"] == 6


def test_the_recording_optimisers_refuse_to_step():
    """Stepping a recording optimiser would move the weights twice and its step count once
    per parameter: it says so instead."""
    _, flat = _same_start(FLAT)
    flat.update(random_batch(torch.Generator().manual_seed(2)), torch.Generator())
    with pytest.raises(RuntimeError, match="steps the weights itself"):
        flat.actor_opt.step()


def test_an_optimiser_record_replaced_behind_its_back_is_taken_in():
    """torch's own `Optimizer.load_state_dict` replaces the record's tensors: the next flat
    step starts from what it loaded (Adam step 2 here, not the agent's own 1)."""
    _, saver = _same_start(FLAT)
    generator = torch.Generator().manual_seed(4)
    for _ in range(2):
        saver.update(random_batch(generator), generator)
    _, loader = _same_start(FLAT)
    loader.update(random_batch(generator), generator)
    loader.critic_opt.load_state_dict(copy.deepcopy(saver.critic_opt.state_dict()))
    loaded = copy.deepcopy(loader.state_dict()["critic_opt"])
    assert loaded["step"] == 2
    loader.update(random_batch(generator), generator)
    after = loader.state_dict()["critic_opt"]
    assert after["step"] == 3
    assert all(not torch.equal(after["exp_avg"][n], v) for n, v in loaded["exp_avg"].items())


@pytest.mark.parametrize("precision", ["fp32", "bf16"])
def test_on_a_cpu_every_path_acts_with_the_fp32_actor(precision):
    """One observation a step: the policy in its weights' fp32 whatever the update's
    precision (bf16 at batch 1 doubled the action's cost), so the reference and the flat
    path act alike from the same weights and noise."""
    reference = SAC(OBS, ACT, SETTINGS, CPU)
    flat = SAC(OBS, ACT, SETTINGS, CPU, Execution.fast(CPU, precision))
    flat.load_state_dict(reference.state_dict())
    obs = torch.randn(OBS, generator=torch.Generator().manual_seed(3)).numpy()
    for deterministic in (False, True):
        actions = [
            agent.act(obs, deterministic, torch.Generator().manual_seed(5))
            for agent in (reference, flat)
        ]
        assert (actions[0] == actions[1]).all()


def _unhook_actor_data(agent: SAC) -> None:
    first = agent.actor.net[0]
    first.weight.data = first.weight.data.clone()


def _replace_a_critic_parameter(agent: SAC) -> None:
    critic = agent.critic
    assert isinstance(critic, StackedTwinCritic)
    critic.weights[0] = torch.nn.Parameter(critic.weights[0].detach().clone())


def _unhook_target_data(agent: SAC) -> None:
    target = agent.critic_target
    assert isinstance(target, StackedTwinCritic)
    target.biases[-1].data = target.biases[-1].data.clone()


def _move_the_actor_to_float64(agent: SAC) -> None:
    agent.actor.double()


UNHOOKINGS = [
    _unhook_actor_data,
    _replace_a_critic_parameter,
    _unhook_target_data,
    _move_the_actor_to_float64,
]


@pytest.mark.parametrize("unhook", UNHOOKINGS, ids=lambda f: f.__name__.strip("_"))
@pytest.mark.parametrize("then", ["load_state_dict", "reset_critic"])
def test_a_parameter_that_no_longer_views_its_flat_buffer_is_refused(unhook, then):
    """The flat update steps its buffers; a parameter given other storage would leave its
    module with stale weights while training went on: the next load or reset says so."""
    _, flat = _same_start(FLAT)
    state = flat.state_dict()
    unhook(flat)
    with pytest.raises(RuntimeError, match="no longer views it"):
        flat.load_state_dict(state) if then == "load_state_dict" else flat.reset_critic()


def test_loads_and_resets_keep_the_parameters_viewing_the_flat_buffers():
    """What every loader does (copies in place) passes the check, and the module then
    shows the flat update's steps."""
    autograd, flat = _same_start(FLAT)
    flat.reset_critic()
    flat.load_state_dict(autograd.state_dict())
    before = flat.actor.net[0].weight.detach().clone()
    flat.update(random_batch(torch.Generator().manual_seed(6)), torch.Generator())
    assert not torch.equal(flat.actor.net[0].weight, before)
    assert all(p.grad is None for p in flat.actor.parameters())  # gradients live flat
